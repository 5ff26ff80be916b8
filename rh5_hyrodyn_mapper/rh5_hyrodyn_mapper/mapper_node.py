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

import time
from collections import Counter
from typing import Any, Final

import numpy as np
from std_msgs.msg import String

from rh5_hyrodyn_mapper.kinematics.base import KinematicsError
from rh5_hyrodyn_mapper.mapping import RobotMapper
from rh5_hyrodyn_mapper.model.urdf import generate_urdf
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, Level, Status, diagnostics_to_msg, time_to_ns
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import LatencyWindow

DIAGNOSTICS_PERIOD_S: Final = 1.0


class MapperNode(SuiteNode):
    """Maps between joint space and actuator space in both directions."""

    def __init__(self) -> None:
        super().__init__(interfaces.MAPPER_NODE, "rh5_hyrodyn_mapper", "params/mapper.yaml")
        self.mapper = RobotMapper(max_condition=self.params["max_condition_number"])
        self._joint_codec_in = JointStateCodec(JOINT_NAMES, what="joint_commands")
        self._actuator_codec_in = JointStateCodec(ACTUATOR_NAMES, what="actuator_states")
        self._actuator_codec_out = JointStateCodec(ACTUATOR_NAMES)
        self._joint_codec_out = JointStateCodec(JOINT_NAMES)
        self._last_q: np.ndarray | None = None  # warm start of the forward kinematics
        self.rejected: Counter[str] = Counter()
        self.clamped: Counter[str] = Counter()
        self.latency = {"joint_commands": LatencyWindow(), "actuator_states": LatencyWindow()}
        if self.params["publish_robot_description"]:
            self.advertise(interfaces.ROBOT_DESCRIPTION)(String(data=generate_urdf()))
        self._publish_actuator_commands = self.advertise(interfaces.ACTUATOR_COMMANDS)
        self._publish_joint_states = self.advertise(interfaces.JOINT_STATES)
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        self.subscribe_stream(interfaces.JOINT_COMMANDS, self._on_joint_commands)
        self.subscribe_stream(interfaces.ACTUATOR_STATES, self._on_actuator_states)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._publish_status)

    def _reject(self, topic: str, reason: str) -> None:
        self.rejected[topic] += 1
        self.get_logger().warning(f"rejected a {topic} message: {reason}", throttle_duration_sec=1.0)

    def _on_joint_commands(self, msg: Any) -> None:
        start = time.perf_counter_ns()
        try:
            q, v, tau = self._joint_codec_in.decode(msg)
            if q is None:
                self._reject("joint_commands", "no positions")
                return
            if not all(x is None or np.isfinite(x).all() for x in (q, v, tau)):
                self._reject("joint_commands", "NaN or inf in the command")
                return
            actuators = self.mapper.to_actuators(q, v, tau=tau)
        except (ValueError, KinematicsError) as err:  # wrong names, singular pose
            self._reject("joint_commands", str(err))
            return
        actuators, clamped = self.mapper.clamp(actuators)
        if clamped.any():
            if not self.params["clamp_to_limits"]:
                names = [ACTUATOR_NAMES[i] for i in np.flatnonzero(clamped)]
                self._reject("joint_commands", f"outside the actuator limits: {names}")
                return
            self.clamped.update(ACTUATOR_NAMES[i] for i in np.flatnonzero(clamped))
        out = self._actuator_codec_out.encode(
            actuators.position, actuators.velocity, actuators.effort, stamp_ns=time_to_ns(msg.header.stamp)
        )
        self._publish_actuator_commands(out)
        self.latency["joint_commands"].add(time.perf_counter_ns() - start)

    def _on_actuator_states(self, msg: Any) -> None:
        start = time.perf_counter_ns()
        try:
            l, ld, f = self._actuator_codec_in.decode(msg)
            if l is None or not all(x is None or np.isfinite(x).all() for x in (l, ld, f)):
                self._reject("actuator_states", "missing positions, NaN or inf")
                return
            joints = self.mapper.to_joints(l, ld, f, q_guess=self._last_q)
        except (ValueError, KinematicsError) as err:  # wrong names, lengths that do not assemble
            self._last_q = None
            self._reject("actuator_states", str(err))
            return
        self._last_q = joints.position
        out = self._joint_codec_out.encode(
            joints.position, joints.velocity, joints.effort, stamp_ns=time_to_ns(msg.header.stamp)
        )
        self._publish_joint_states(out)
        self.latency["actuator_states"].add(time.perf_counter_ns() - start)

    def _publish_status(self) -> None:
        level = Level.WARN if self.rejected or self.clamped else Level.OK
        values: dict[str, object] = {f"rejected.{k}": n for k, n in self.rejected.items()}
        values.update({f"clamped.{k}": n for k, n in self.clamped.items()})
        for topic, window in self.latency.items():
            values.update({f"latency.{topic}.{k}": round(x, 1) for k, x in window.percentiles_us().items()})
        message = "ok" if level == Level.OK else "commands clamped or rejected since start"
        status = Status("rh5/mapper", level, message, values, hardware_id="rh5")
        self._publish_diagnostics(diagnostics_to_msg([status], stamp_ns=self.get_clock().now().nanoseconds))

    def summary(self) -> dict[str, Any]:
        """Adds rejections, clamping and processing latency to the base summary."""
        return {
            **super().summary(),
            "rejected": dict(self.rejected),
            "clamped": dict(self.clamped),
            "latency_us": {topic: window.percentiles_us() for topic, window in self.latency.items()},
        }


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_hyrodyn_mapper mapper_node``."""
    run_node(MapperNode, args)
