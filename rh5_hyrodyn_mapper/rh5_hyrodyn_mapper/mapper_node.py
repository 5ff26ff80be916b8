"""The mapper node: joint commands to actuator setpoints, actuator readings back to joint states.

``joint_commands`` (independent joints: position, velocity, effort) become
``actuator_commands`` (actuator names: length [m], velocity [m/s], force [N]; rotary joints
unchanged) through the closed-form inverse kinematics and f = J^-T tau; ``actuator_states``
become ``joint_states`` through the warm-started forward kinematics and tau = J^T f.
Out-of-limit setpoints are clamped and counted; NaN/inf, unknown joint names and
singular poses are rejected with a logged reason and never forwarded. The URDF is
published once on the latched ``robot_description`` topic.
"""

from __future__ import annotations

from typing import Any, Final

from std_msgs.msg import String

from rh5_hyrodyn_mapper.kinematics import build_submechanisms
from rh5_hyrodyn_mapper.mapper_core import MapperCore
from rh5_hyrodyn_mapper.mapping import RobotMapper
from rh5_hyrodyn_mapper.model.urdf import generate_urdf
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, Level, Status, diagnostics_to_msg, time_to_ns
from rh5_msgs_py.diagnostic_keys import HARDWARE_ID, MAPPER_STATUS, MapperKeys
from rh5_msgs_py.diagnostic_tasks import Increases, task_status
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node

DIAGNOSTICS_PERIOD_S: Final = 1.0


class MapperNode(SuiteNode):
    """Maps between joint space and actuator space in both directions.

    ``composed=True``: hosted by the control process (rh5_bringup.control.node), whose cycle calls ``core``
    directly and publishes the results through ``publish_joint_states`` / ``publish_actuator_commands``;
    the node then subscribes to no 1 kHz stream.
    """

    def __init__(self, *, composed: bool = False) -> None:
        super().__init__(interfaces.MAPPER_NODE, "rh5_hyrodyn_mapper", "params/mapper.yaml")
        self.core = MapperCore(
            self._build_mapper(), clamp_to_limits=self.params["clamp_to_limits"], on_reject=self._log_rejection
        )
        self._increases = Increases()
        self._joint_codec_in = JointStateCodec(JOINT_NAMES, what="joint_commands")
        self._actuator_codec_in = JointStateCodec(ACTUATOR_NAMES, what="actuator_states")
        self.actuator_codec_out = JointStateCodec(ACTUATOR_NAMES)
        self.joint_codec_out = JointStateCodec(JOINT_NAMES)
        if self.params["publish_robot_description"]:
            self.advertise(interfaces.ROBOT_DESCRIPTION)(String(data=generate_urdf(visuals=True)))
        if not composed:  # composed: the control process's stream publisher sends them
            self.publish_actuator_commands = self.advertise(interfaces.ACTUATOR_COMMANDS)
            self.publish_joint_states = self.advertise(interfaces.JOINT_STATES)
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        if not composed:
            self.subscribe_stream(interfaces.JOINT_COMMANDS, self._on_joint_commands)
            self.subscribe_stream(interfaces.ACTUATOR_STATES, self._on_actuator_states)
        if not composed:  # composed: the control node publishes every hosted node's status on one timer
            self.create_wall_timer(DIAGNOSTICS_PERIOD_S, self.publish_status)
        core = self.core
        self.apply_live(  # the next map uses the new setting; the loop never waits for it
            {
                "clamp_to_limits": lambda on: lambda: setattr(core, "clamp_to_limits", bool(on)),
                "max_condition_number": lambda _: self._swap_mapper,
                "fk_tolerance": lambda _: self._swap_mapper,
                "fk_max_iterations": lambda _: self._swap_mapper,
            }
        )

    @property
    def mapper(self) -> RobotMapper:
        """The maps the node uses now."""
        return self.core.mapper

    def _build_mapper(self) -> RobotMapper:
        """The robot's maps with this node's singularity guard and forward-kinematics stop criteria."""
        params = self.params
        newton = {"tolerance": params["fk_tolerance"], "max_iterations": params["fk_max_iterations"]}
        models = tuple(m.with_newton(**newton) if hasattr(m, "with_newton") else m for m in build_submechanisms())
        return RobotMapper(models, max_condition=params["max_condition_number"])

    def _swap_mapper(self) -> None:
        """Rebuild the maps from the accepted parameters (a few ms) and hand them to the core in one assignment."""
        self.core.mapper = self._build_mapper()

    def _log_rejection(self, topic: str, reason: str) -> None:
        self.get_logger().warning(f"rejected a {topic} message: {reason}", throttle_duration_sec=1.0)

    @property
    def rejected(self) -> Any:
        """Refusals per input topic."""
        return self.core.rejected

    @property
    def clamped(self) -> Any:
        """Clamped setpoints per actuator."""
        return self.core.clamped

    def _on_joint_commands(self, msg: Any) -> None:
        try:
            q, v, tau = self._joint_codec_in.decode(msg)
        except ValueError as err:  # wrong names
            self.core.reject("joint_commands", str(err))
            return
        actuators = self.core.to_actuator_command(q, v, tau)
        if actuators is not None:
            self.publish_actuator_commands(
                self.actuator_codec_out.encode(
                    actuators.position, actuators.velocity, actuators.effort, stamp_ns=time_to_ns(msg.header.stamp)
                )
            )

    def _on_actuator_states(self, msg: Any) -> None:
        try:
            l, ld, f = self._actuator_codec_in.decode(msg)
        except ValueError as err:  # wrong names
            self.core.reject("actuator_states", str(err))
            return
        joints = self.core.to_joint_state(l, ld, f)
        if joints is not None:
            self.publish_joint_states(
                self.joint_codec_out.encode(
                    joints.position, joints.velocity, joints.effort, stamp_ns=time_to_ns(msg.header.stamp)
                )
            )

    def publish_status(self) -> None:
        self.status_gate()
        level = Level.WARN if self.rejected or self.clamped else Level.OK
        values: dict[str, object] = {f"{MapperKeys.REJECTED_PREFIX}{k}": n for k, n in self.rejected.items()}
        values.update({f"{MapperKeys.CLAMPED_PREFIX}{k}": n for k, n in self.clamped.items()})
        for topic, window in self.core.latency.items():
            values.update({f"latency.{topic}.{k}": round(x, 1) for k, x in window.percentiles_us().items()})
        message = "ok" if level == Level.OK else "commands clamped or rejected since start"
        status = Status(MAPPER_STATUS, level, message, values, hardware_id=HARDWARE_ID)
        statuses = [status, *self.task_statuses()]
        self._publish_diagnostics(diagnostics_to_msg(statuses, stamp_ns=self.stamp_ns()))

    def task_statuses(self) -> list[Status]:
        """``mapper: limits`` (WARN while setpoints are clamped) and ``mapper: kinematics`` (ERROR while maps are
        refused: NaN, unknown names, singular poses), each judged on what happened since the last report."""
        clamped = sum(self.clamped.values())
        rejected = sum(self.rejected.values())
        new_clamps = int(self._increases("clamped", clamped))
        new_rejections = int(self._increases("rejected", rejected))
        limits = task_status(
            "mapper",
            "limits",
            Level.WARN if new_clamps else Level.OK,
            "setpoints clamped to the actuator limits" if new_clamps else "within limits",
            {"new_clamps": new_clamps, "clamps": clamped},
        )
        kinematics = task_status(
            "mapper",
            "kinematics",
            Level.ERROR if new_rejections else Level.OK,
            "maps refused" if new_rejections else "ok",
            {"new_rejections": new_rejections, "rejections": rejected},
        )
        return [limits, kinematics]

    def summary(self) -> dict[str, Any]:
        """Adds rejections, clamping and processing latency to the base summary."""
        return {
            **super().summary(),
            "rejected": dict(self.rejected),
            "clamped": dict(self.clamped),
            "latency_us": {topic: window.percentiles_us() for topic, window in self.core.latency.items()},
        }


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_hyrodyn_mapper mapper_node``."""
    run_node(MapperNode, args)
