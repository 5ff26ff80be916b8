"""The stabilizer node: plays the planned motion at 1 kHz and stabilises it in joint space.

A dedicated loop thread (rh5_msgs_py.realtime.DeadlineLoop) runs StabilizerCore every
millisecond and publishes ``joint_commands`` in every active state; ROS callbacks only
validate inputs and hand them over through latest-value slots (rh5_msgs_py.realtime.LatestValue). Services
``~/start``, ``~/stop`` and ``~/hold`` answer with the reason when they refuse. Motions come on the latched
``planned_trajectory`` topic or as goals of the ``~/follow_joint_trajectory`` action
(rh5_joint_stabilizer.trajectory_action, as joint_trajectory_controller serves it).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any, Final

import numpy as np
import yaml
from std_srvs.srv import Trigger

from rh5_hyrodyn_mapper.model import joint_limits
from rh5_joint_stabilizer.balance import AnkleBalanceCorrection, ankle_axes_world
from rh5_joint_stabilizer.controller import Command, Measurement, SafetyLimits, StabilizerCore, State, load_gains
from rh5_joint_stabilizer.goal_check import Tolerances
from rh5_joint_stabilizer.reference import PlannedTrajectory, TrajectoryRejectedError, validate_trajectory
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, Level, Status, diagnostics_to_msg, joint_trajectory_from_cdr
from rh5_msgs_py.diagnostic_keys import HARDWARE_ID, STABILIZER_STATUS, StabilizerKeys
from rh5_msgs_py.diagnostic_tasks import task_status
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import DeadlineLoop, LatestValue
from rh5_msgs_py.trajectory_file import TrajectoryFileError, load_trajectory

DIAGNOSTICS_PERIOD_S: Final = 1.0
BALANCE_GAIN: Final = 0.5
BALANCE_MAX_CORRECTION: Final = 0.1  # rad


class TrackingWindow:
    """Tracking errors of the last second, for RMS and max per joint on /diagnostics."""

    def __init__(self, size: int = 1000) -> None:
        self._errors = np.zeros((size, NUM_JOINTS))
        self._count = 0

    def add(self, error: np.ndarray) -> None:
        """Record one tick's tracking error."""
        self._errors[self._count % len(self._errors)] = error
        self._count += 1

    def rms_and_max(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint RMS and max |error| over the window (zeros when empty)."""
        window = self._errors[: min(self._count, len(self._errors))]
        if not len(window):
            return np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS)
        return np.sqrt(np.mean(window**2, axis=0)), np.max(np.abs(window), axis=0)


class StabilizerNode(SuiteNode):
    """ROS wiring around StabilizerCore and its 1 kHz loop.

    ``composed=True``: hosted by the control process (rh5_bringup.control.node), whose cycle calls ``step``
    with the same cycle's measurement and publishes ``joint_commands``; the node then runs no loop and
    subscribes to neither ``joint_states`` nor the driver's estop topic (the cycle passes the latch on).
    """

    def __init__(self, *, composed: bool = False) -> None:
        super().__init__(interfaces.STABILIZER_NODE, "rh5_joint_stabilizer", "params/stabilizer.yaml")
        params = self.params
        limits = joint_limits()
        self.velocity_limits = np.asarray(limits.velocity_max)
        self.balance: AnkleBalanceCorrection | None = None
        if params["balance_correction"]:
            self.balance = self._balance_correction(params["state_timeout_s"])
        self.events: deque[str] = deque(maxlen=50)
        self.core = StabilizerCore(
            load_gains(params["gains_file"] or None),
            np.asarray(limits.torque_max),
            ramp_max_velocity=params["ramp_max_velocity"],
            ramp_max_acceleration=params["ramp_max_acceleration"],
            safety=SafetyLimits(
                int(params["state_timeout_s"] * 1e9), params["max_tracking_error_rad"], params["rest_velocity_rad_s"]
            ),
            on_event=self._log_event,
            correction=self.balance,
        )
        self.measurement: LatestValue[Measurement] = LatestValue()
        self._composed = composed
        self._reported_state = self.core.state
        self.state_changed = False
        self._ros_playback = params["playback_clock"] == "ros"
        self.tracking = TrackingWindow()
        self._state_codec = JointStateCodec(JOINT_NAMES, what="joint_states")
        self.command_codec = JointStateCodec(JOINT_NAMES)
        if not composed:  # composed: the control process's stream publisher sends them
            self.publish_commands = self.advertise(interfaces.JOINT_COMMANDS)
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        # raw: a long trajectory converted by rclpy holds the interpreter lock for tens of ms (a stall of the cycle)
        self.subscribe(interfaces.PLANNED_TRAJECTORY, self._on_trajectory, raw=True)
        if not composed:
            self.subscribe_stream(interfaces.JOINT_STATES, self._on_joint_states)
            self.subscribe(interfaces.DRIVER_ESTOP, self._on_estop)
        self._base_pose_subscription = None
        if self.balance is not None:
            self._base_pose_subscription = self.subscribe(interfaces.SIM_BASE_POSE, self._on_base_pose)
        self.create_service(Trigger, interfaces.START_SERVICE, self._on_start)
        self.create_service(Trigger, interfaces.STOP_SERVICE, self._on_stop)
        self.create_service(Trigger, interfaces.HOLD_SERVICE, self._on_hold)
        if not composed:  # composed: the control node publishes every hosted node's status on one timer
            self.create_wall_timer(DIAGNOSTICS_PERIOD_S, self.publish_status)
        self.action = self._action_server()
        if params["trajectory_file"]:
            self._load_file(params["trajectory_file"])
        core = self.core
        self.apply_live(  # reference swaps and attribute writes: the next update uses them, the loop never waits
            {
                "trajectory_file": self._check_trajectory_file,
                "gains_file": self._check_gains_file,
                "state_timeout_s": lambda s: lambda: self._set_safety(state_timeout_ns=int(s * 1e9)),
                "max_tracking_error_rad": lambda e: lambda: self._set_safety(max_tracking_error=float(e)),
                "rest_velocity_rad_s": lambda v: lambda: self._set_safety(rest_velocity=float(v)),
                "ramp_max_velocity": lambda v: lambda: setattr(core, "ramp_max_velocity", float(v)),
                "ramp_max_acceleration": lambda a: lambda: setattr(core, "ramp_max_acceleration", float(a)),
                "balance_correction": lambda on: lambda: self._set_balance(bool(on)),
                "path_tolerance_rad": lambda _: None,  # read at each goal
                "goal_tolerance_rad": lambda _: None,
                "goal_time_tolerance_s": lambda _: None,
            }
        )
        self.loop: DeadlineLoop | None = None
        if not composed:
            self.loop = self.start_loop(params["rate_hz"], self._tick, "stabilizer-1kHz", params["realtime_priority"])

    def _action_server(self) -> Any:
        """``~/follow_joint_trajectory``, or None (with a warning) where control_msgs is missing."""
        try:
            from rh5_joint_stabilizer.trajectory_action import TrajectoryActionServer  # noqa: PLC0415
        except ImportError as err:
            self.get_logger().warning(f"no ~/follow_joint_trajectory: {err} (make venv builds control_msgs)")
            return None

        def defaults() -> Tolerances:
            p = self.params
            return Tolerances.uniform(p["path_tolerance_rad"], p["goal_tolerance_rad"], p["goal_time_tolerance_s"])

        def rejected(reason: str) -> None:
            self.events.append(f"goal rejected: {reason}")
            self.publish_status()

        def measured() -> Measurement | None:
            return self.measurement.try_get()[0]

        return TrajectoryActionServer(
            self,
            self.core,
            measurement=measured,
            velocity_limits=self.velocity_limits,
            defaults=defaults,
            on_rejected=rejected,
        )

    # --- parameters at run time ------------------------------------------------------------------------------------

    def _check_trajectory_file(self, path: str) -> Callable[[], None] | None:
        """A new trajectory file is loaded once accepted (refused now if it does not exist)."""
        if not path:
            return None
        if not Path(path).is_file():
            msg = f"no such file: {path}"
            raise ValueError(msg)
        return lambda: self._load_file(path)

    def _check_gains_file(self, path: str) -> Callable[[], None]:
        """The gains are read now (a bad file is refused with the reason) and take effect on the next update."""
        try:
            gains = load_gains(path or None)
        except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as err:
            msg = f"cannot use gains file {path!r}: {err}"
            raise ValueError(msg) from None
        return lambda: setattr(self.core, "gains", gains)

    def _set_safety(self, **changes: float) -> None:
        self.core.safety = replace(self.core.safety, **changes)

    @staticmethod
    def _balance_correction(state_timeout_s: float) -> AnkleBalanceCorrection:
        return AnkleBalanceCorrection(
            BALANCE_GAIN, BALANCE_MAX_CORRECTION, int(state_timeout_s * 1e9) * 10, ankle_axes_world()
        )

    def _set_balance(self, on: bool) -> None:
        """Switch the ankle balance correction (it needs the simulated base pose, subscribed on first use)."""
        if on and self.balance is None:
            self.balance = self._balance_correction(self.params["state_timeout_s"])
        if on and self._base_pose_subscription is None:
            self._base_pose_subscription = self.subscribe(interfaces.SIM_BASE_POSE, self._on_base_pose)
        self.core.correction = self.balance if on else None

    def _log_event(self, text: str) -> None:
        self.events.append(text)
        self.get_logger().info(text)

    # --- inputs ------------------------------------------------------------------------------------------------------

    def _accept(self, trajectory: PlannedTrajectory, source: str) -> None:
        ok, reason = self.core.load(trajectory)
        if not ok:
            self.get_logger().warning(f"trajectory from {source} not loaded: {reason}")

    def _load_file(self, path: str) -> None:
        try:
            data = load_trajectory(path)
            trajectory = validate_trajectory(
                JOINT_NAMES,
                data.times,
                data.joint_positions(),
                data.joint_velocities(),
                self._file_efforts(data),
                velocity_limits=self.velocity_limits,
            )
        except (OSError, TrajectoryFileError, TrajectoryRejectedError) as err:
            self.get_logger().error(f"trajectory file {path} rejected: {err}")
            self.core.reject(f"trajectory file {path}: {err}")
            return
        self._accept(trajectory, path)

    @staticmethod
    def _file_efforts(data: Any) -> np.ndarray:
        """Joint torques per knot from the file's controls (the last knot repeats the last control)."""
        controls = np.asarray(data.controls)
        if len(controls) == len(data.times):
            return controls
        return np.vstack([controls, controls[-1:]]) if len(controls) else np.zeros((len(data.times), NUM_JOINTS))

    def _on_trajectory(self, msg: Any) -> None:
        try:
            arrays = joint_trajectory_from_cdr(msg, allow_extra=True)
            trajectory = validate_trajectory(
                arrays.joint_names,
                arrays.times,
                arrays.positions,
                arrays.velocities,
                arrays.efforts,
                velocity_limits=self.velocity_limits,
            )
        except (ValueError, TrajectoryRejectedError) as err:
            self.get_logger().error(f"planned_trajectory rejected: {err}")
            self.events.append(f"trajectory rejected: {err}")
            self.core.reject(f"planned_trajectory: {err}")
        else:
            self._accept(trajectory, "planned_trajectory")
        # at once, not at the next 1 Hz status: on a simulation's /clock that can be many wall seconds away
        self.publish_status()

    def _on_joint_states(self, msg: Any) -> None:
        try:
            position, velocity, _ = self._state_codec.decode(msg)
        except ValueError as err:
            self.get_logger().warning(f"joint_states ignored: {err}", throttle_duration_sec=1.0)
            return
        if position is None or not np.isfinite(position).all():
            return
        velocity = np.zeros(NUM_JOINTS) if velocity is None or not np.isfinite(velocity).all() else velocity
        self.measurement.set(Measurement(position, velocity, time.monotonic_ns()))

    def _on_estop(self, msg: Any) -> None:
        self.core.set_estop(bool(msg.data))

    def _on_base_pose(self, msg: Any) -> None:
        o = msg.pose.orientation
        self.balance.base_orientation.set(np.array([o.x, o.y, o.z, o.w]))

    # --- services ----------------------------------------------------------------------------------------------------

    def _on_start(self, _request: Any, response: Any) -> Any:
        measurement, _, _ = self.measurement.try_get()
        response.success, response.message = self.core.request_start(measurement)
        return response

    def _on_stop(self, _request: Any, response: Any) -> Any:
        response.success, response.message = self.core.request_stop()
        return response

    def _on_hold(self, _request: Any, response: Any) -> Any:
        response.success, response.message = self.core.request_hold()
        return response

    # --- the 1 kHz loop ----------------------------------------------------------------------------------------------

    def step(self, now_ns: int, period_ns: int, measurement: Measurement | None) -> Command | None:
        """One stabilizer update on ``measurement``: the command to send (None when idle or stopped).

        ``state_changed`` then says whether the state moved, which is published at once (recordings then know
        when playback started to the millisecond).
        """
        if self._composed and measurement is not None:
            self.measurement.set(measurement, measurement.stamp_ns)  # what ~/start ramps in from
        playback_ns = self.get_clock().now().nanoseconds if self._ros_playback else None
        command = self.core.update(now_ns, period_ns, measurement, playback_ns)
        self.state_changed = self.core.state is not self._reported_state
        self._reported_state = self.core.state
        if command is not None:
            self.tracking.add(self.core.tracking_error)
        return command

    def _tick(self, now_ns: int, period_ns: int) -> None:
        measurement, _, _ = self.measurement.try_get()
        command = self.step(now_ns, period_ns, measurement)
        if self.state_changed:
            self.publish_status()
        if command is not None:
            self.publish_commands(
                self.command_codec.encode(
                    command.position,
                    command.velocity,
                    command.effort,
                    stamp_ns=self.stamp_ns() if self.sim_time else time.time_ns(),
                )
            )

    # --- reporting ---------------------------------------------------------------------------------------------------

    def publish_status(self) -> None:
        """The stabilizer's /diagnostics status: state, reason, loop timing (on its own) and tracking errors."""
        self.status_gate()
        rms, peak = self.tracking.rms_and_max()
        trajectory = self.core.trajectory
        values: dict[str, object] = {
            StabilizerKeys.STATE: self.core.state.value,
            StabilizerKeys.REASON: self.core.last_reason,
            StabilizerKeys.TRAJECTORY_DURATION_S: round(trajectory.duration, 6) if trajectory is not None else "none",
            StabilizerKeys.TRAJECTORY_REJECTED: self.core.rejection,
        }
        if self.loop is not None:
            values.update(self.loop.diagnostics())
        values.update({f"rms_error.{j}": round(float(e), 6) for j, e in zip(JOINT_NAMES, rms, strict=True)})
        values.update({f"max_error.{j}": round(float(e), 6) for j, e in zip(JOINT_NAMES, peak, strict=True)})
        if self.core.correction is not None and self.balance is not None:
            values["balance_correction_active"] = self.balance.active
        if self.action is not None:
            values.update({f"action.{k}": v for k, v in self.action.counts.items()})
            values["action.last_result"] = self.action.last_result
            values["action.goal_rejected"] = self.action.rejection
        level = (
            Level.WARN if self.core.state == State.HOLDING and "requested" not in self.core.last_reason else Level.OK
        )
        if self.loop is not None and self.loop.error is not None:
            level, values[StabilizerKeys.LOOP_ERROR] = Level.ERROR, repr(self.loop.error)
        message = self.core.last_reason or self.core.state.value
        status = Status(STABILIZER_STATUS, level, message, values, HARDWARE_ID)
        statuses = [status, *self.task_statuses(peak)]
        # on the node's clock: the simulation's under use_sim_time, as every stamp of the suite then is
        self._publish_diagnostics(diagnostics_to_msg(statuses, stamp_ns=self.stamp_ns()))

    def task_statuses(self, peak: np.ndarray) -> list[Status]:
        """``stabilizer: tracking`` (WARN when it holds for a reason other than a request or the end of the motion)
        and ``stabilizer: trajectory`` (ERROR while the last trajectory or goal offered was rejected)."""
        core = self.core
        worst = int(np.argmax(peak))
        values = {"state": core.state.value, "max_error_rad": round(float(peak[worst]), 6)}
        values["worst_joint"] = JOINT_NAMES[worst]
        requested = any(word in core.last_reason for word in ("requested", "finished"))
        if core.state == State.HOLDING and not requested:
            tracking = task_status(
                "stabilizer", "tracking", Level.WARN, "holding", {**values, "reason": core.last_reason}
            )
        elif core.state == State.STOPPED and "emergency" in core.last_reason:
            tracking = task_status("stabilizer", "tracking", Level.ERROR, "stopped by the emergency stop", values)
        else:
            tracking = task_status("stabilizer", "tracking", Level.OK, core.state.value, values)
        rejection = core.rejection or (self.action.rejection if self.action is not None else "")
        if rejection:
            trajectory = task_status("stabilizer", "trajectory", Level.ERROR, "rejected", {"reason": rejection})
        else:
            loaded = "loaded" if core.trajectory is not None else "none"
            trajectory = task_status("stabilizer", "trajectory", Level.OK, loaded)
        return [tracking, trajectory]

    def summary(self) -> dict[str, Any]:
        """Adds the state, the loop timing and the recent events to the base summary."""
        return {
            **super().summary(),
            "state": self.core.state.value,
            **({} if self.loop is None else {"loop": self.loop.stats().as_dict()}),
            "events": list(self.events)[-10:],
        }

    def destroy_node(self) -> None:
        """Stop the loop thread and the action server before the node goes away."""
        if self.loop is not None:
            self.loop.stop()
        if self.action is not None:
            self.action.destroy()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_joint_stabilizer stabilizer_node``."""
    run_node(StabilizerNode, args)
