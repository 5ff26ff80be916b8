"""The stabilizer's state machine and control law, free of ROS and of wall-clock time.

``update(now_ns, period_ns, measurement)`` is called every millisecond by the node's loop
(or by a test with synthetic time): it advances idle -> ramp_in -> playing -> holding ->
stopped, applies the safety rules, and returns the joint command
tau = tau_ff + Kp (q_ref - q) + Kd (v_ref - v), saturated to the joint torque limits.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import numpy as np
import yaml

from rh5_joint_stabilizer.reference import PlannedTrajectory, RampIn, ReferenceSample
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_GROUPS, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS


class State(Enum):
    """Stabilizer states, with their wire names (used in logs, responses and diagnostics)."""

    IDLE = "idle"
    RAMP_IN = "ramp_in"
    PLAYING = "playing"
    HOLDING = "holding"
    STOPPED = "stopped"


ACTIVE_STATES = (State.RAMP_IN, State.PLAYING, State.HOLDING)


@dataclass(frozen=True)
class Gains:
    """PD gains per joint (JOINT_NAMES order): Kp [Nm/rad], Kd [Nm s/rad]."""

    kp: FloatArray
    kd: FloatArray


def load_gains(path: str | Path | None = None) -> Gains:
    """Read Kp/Kd per joint group from YAML (default: the packaged gains.yaml); every group is required."""
    if path:
        text = Path(path).read_text(encoding="utf-8")
    else:
        text = resources.files("rh5_joint_stabilizer").joinpath("gains.yaml").read_text(encoding="utf-8")
    groups = yaml.safe_load(text)["groups"]
    missing = set(JOINT_GROUPS) - set(groups)
    if missing:
        msg = f"gains: no entry for joint groups {sorted(missing)}"
        raise ValueError(msg)
    kp, kd = np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS)
    for group, joints in JOINT_GROUPS.items():
        entry = groups[group]
        if entry["kp"] < 0 or entry["kd"] < 0:
            msg = f"gains: negative gain in group {group}"
            raise ValueError(msg)
        idx = [JOINT_INDEX[j] for j in joints]
        kp[idx], kd[idx] = entry["kp"], entry["kd"]
    return Gains(kp, kd)


@dataclass(frozen=True)
class SafetyLimits:
    """Thresholds of the safety rules."""

    state_timeout_ns: int  # joint_states older than this -> hold
    max_tracking_error: float  # rad; larger error in ramp-in or playback -> hold
    rest_velocity: float = 0.05  # rad/s; the robot is at rest when every joint is slower


class Measurement(NamedTuple):
    """Measured joint state and when it arrived (monotonic ns)."""

    position: FloatArray
    velocity: FloatArray
    stamp_ns: int


class Command(NamedTuple):
    """What goes out on joint_commands: reference position and velocity, and the torque."""

    position: FloatArray
    velocity: FloatArray
    effort: FloatArray


class StabilizerCore:
    """Playback, ramp-in, hold and stop with the safety rules; thread-safe requests, one ``update`` per tick."""

    def __init__(
        self,
        gains: Gains,
        torque_limits: FloatArray,
        *,
        ramp_max_velocity: float,
        ramp_max_acceleration: float,
        safety: SafetyLimits,
        on_event: Callable[[str], None] = lambda _text: None,
        correction: Callable[[ReferenceSample], ReferenceSample] | None = None,
    ) -> None:
        self.gains = gains
        self.torque_limits = np.asarray(torque_limits, dtype=np.float64)
        self.ramp_max_velocity = ramp_max_velocity
        self.ramp_max_acceleration = ramp_max_acceleration
        self.safety = safety
        self._on_event = on_event
        self.correction = correction
        self._lock = threading.Lock()
        self.state = State.IDLE
        self.trajectory: PlannedTrajectory | None = None
        self.rejection = ""
        """Why the last trajectory offered was rejected (empty after one is accepted)."""
        self.estopped = False
        self.last_reason = ""
        self._ramp: RampIn | None = None
        self._phase_start_ns = 0
        self._hold: ReferenceSample | None = None
        self._last_command: Command | None = None
        self._pending_start = False
        self._start_from_reference = False
        self._hold_request = False
        self._stop_request = False
        self.tracking_error = np.zeros(NUM_JOINTS)

    # --- requests (service callbacks, any thread) ------------------------------------------------------------------

    def load(self, trajectory: PlannedTrajectory) -> tuple[bool, str]:
        """Accept a validated trajectory unless one is being ramped into or played."""
        with self._lock:
            if self.state in (State.RAMP_IN, State.PLAYING):
                return False, f"refused: a trajectory is {self.state.value.replace('_', ' ')}; call ~/hold first"
            self.trajectory = trajectory
            self.rejection = ""
        self._on_event(f"trajectory loaded: {len(trajectory.times)} points, {trajectory.duration:.3f} s")
        return True, "trajectory loaded"

    def reject(self, reason: str) -> None:
        """A new trajectory was rejected: drop the previous one too (unless it is being played), so that a start
        cannot play a trajectory other than the one last sent; the refusal then names the reason."""
        with self._lock:
            self.rejection = reason
            if self.state not in (State.RAMP_IN, State.PLAYING):
                self.trajectory = None

    def request_start(self, measurement: Measurement | None) -> tuple[bool, str]:
        """Ramp in from the measured pose and play; refused without trajectory, at motion, under estop."""
        with self._lock:
            if self.estopped:
                return False, "refused: emergency stop is latched in the driver"
            if self.trajectory is None:
                why = f"; the last one was rejected: {self.rejection}" if self.rejection else ""
                return False, f"refused: no trajectory (publish planned_trajectory or set trajectory_file){why}"
            if self.state in (State.RAMP_IN, State.PLAYING):
                return False, f"refused: already {self.state.value}"
            if measurement is None:
                return False, "refused: no joint_states received"
            fastest = int(np.argmax(np.abs(measurement.velocity)))
            speed = float(abs(measurement.velocity[fastest]))
            if speed > self.safety.rest_velocity:
                return False, f"refused: robot not at rest ({JOINT_NAMES[fastest]} at {speed:.3f} rad/s)"
            self._pending_start = True
        return True, "starting: ramp-in to the first trajectory sample"

    def request_play(self, trajectory: PlannedTrajectory, measurement: Measurement | None) -> tuple[bool, str]:
        """Play ``trajectory`` now (a FollowJointTrajectory goal): as ``load`` + ``request_start``, and also while
        one is ramped into or played, whose place it takes, ramping in from the current reference."""
        with self._lock:
            if self.estopped:
                return False, "refused: emergency stop is latched in the driver"
            if measurement is None:
                return False, "refused: no joint_states received"
            moving = self.state in (State.RAMP_IN, State.PLAYING) and self._last_command is not None
            if not moving:
                fastest = int(np.argmax(np.abs(measurement.velocity)))
                speed = float(abs(measurement.velocity[fastest]))
                if speed > self.safety.rest_velocity:
                    return False, f"refused: robot not at rest ({JOINT_NAMES[fastest]} at {speed:.3f} rad/s)"
            self.trajectory, self.rejection = trajectory, ""
            self._pending_start, self._start_from_reference = True, moving
        self._on_event(f"trajectory to play: {len(trajectory.times)} points, {trajectory.duration:.3f} s")
        return True, "starting: ramp-in to the first trajectory sample"

    @property
    def start_pending(self) -> bool:
        """Whether a requested start waits for the next update."""
        return self._pending_start

    @property
    def last_command(self) -> Command | None:
        """The command of the latest update (its position and velocity are the reference); None before one."""
        return self._last_command

    def request_hold(self) -> tuple[bool, str]:
        """Hold the current reference (from ramp-in or playback)."""
        with self._lock:
            if self.state not in (State.RAMP_IN, State.PLAYING):
                return False, f"refused: nothing to hold in state {self.state.value}"
            self._hold_request = True
        return True, "holding"

    def request_stop(self) -> tuple[bool, str]:
        """Stop commanding: the driver's command timeout then makes the boards hold."""
        with self._lock:
            if self.state in (State.IDLE, State.STOPPED):
                return False, f"refused: already {self.state.value}"
            self._stop_request = True
        return True, "stopping"

    def set_estop(self, estopped: bool) -> None:
        """The driver's emergency-stop latch (stop at once while set)."""
        with self._lock:
            self.estopped = estopped

    # --- the 1 kHz step --------------------------------------------------------------------------------------------

    def _enter(self, state: State, now_ns: int, reason: str) -> None:
        self._on_event(f"{self.state.value} -> {state.value}: {reason}")
        self.state, self._phase_start_ns, self.last_reason = state, now_ns, reason

    def _hold_at(self, reference: ReferenceSample) -> ReferenceSample:
        return ReferenceSample(reference.position, np.zeros(NUM_JOINTS), reference.effort)

    def update(
        self, now_ns: int, period_ns: int, measurement: Measurement | None, playback_ns: int | None = None
    ) -> Command | None:
        """Advance one tick; return the command to publish (None when idle or stopped).

        ``now_ns`` (monotonic) judges the age of ``measurement``; ``playback_ns`` (default ``now_ns``) is the
        clock the ramp-in and the trajectory are played on: a simulation's time when it runs slower than real time.
        """
        del period_ns  # the references are sampled at absolute time; the period is implicit
        with self._lock:
            return self._update(now_ns, measurement, now_ns if playback_ns is None else playback_ns)

    def _update(self, now_ns: int, measurement: Measurement | None, play_ns: int) -> Command | None:
        if self.estopped and self.state in ACTIVE_STATES:
            self._enter(State.STOPPED, play_ns, "emergency stop")
        if self._stop_request:
            self._stop_request = False
            if self.state in ACTIVE_STATES:
                self._enter(State.STOPPED, play_ns, "stop requested")
        if self.state in (State.STOPPED, State.IDLE) and not self._pending_start:
            return None
        stale = measurement is None or now_ns - measurement.stamp_ns > self.safety.state_timeout_ns
        if self._pending_start:
            self._pending_start = False
            if stale or self.trajectory is None:
                self._on_event("start dropped: joint_states went stale")
            else:
                first = self.trajectory.sample(0.0)
                reference = self._last_command if self._start_from_reference else None
                start = (measurement.position if reference is None else reference.position).copy()
                self._ramp = RampIn(start, first.position, self.ramp_max_velocity, self.ramp_max_acceleration)
                self._enter(State.RAMP_IN, play_ns, f"ramp-in over {self._ramp.duration:.2f} s")
        if stale:
            if self._last_command is None:
                return None
            if self.state in (State.RAMP_IN, State.PLAYING):
                age = "none" if measurement is None else f"{(now_ns - measurement.stamp_ns) / 1e6:.1f} ms old"
                self._hold = ReferenceSample(
                    self._last_command.position, np.zeros(NUM_JOINTS), self._last_command.effort
                )
                self._enter(State.HOLDING, play_ns, f"joint_states stale ({age})")
            return Command(self._last_command.position, np.zeros(NUM_JOINTS), self._last_command.effort)
        reference = self._reference(play_ns)
        if self.correction is not None:
            reference = self.correction(reference)
        self.tracking_error = reference.position - measurement.position
        worst = int(np.argmax(np.abs(self.tracking_error)))
        if (
            self.state in (State.RAMP_IN, State.PLAYING)
            and abs(self.tracking_error[worst]) > self.safety.max_tracking_error
        ):
            self._hold = self._hold_at(ReferenceSample(measurement.position, np.zeros(NUM_JOINTS), reference.effort))
            self._enter(
                State.HOLDING,
                play_ns,
                f"tracking error of {JOINT_NAMES[worst]} {self.tracking_error[worst]:+.3f} rad "
                f"exceeds {self.safety.max_tracking_error} rad",
            )
            reference = self._hold
            self.tracking_error = reference.position - measurement.position
        torque = (
            reference.effort
            + self.gains.kp * self.tracking_error
            + self.gains.kd * (reference.velocity - measurement.velocity)
        )
        np.clip(torque, -self.torque_limits, self.torque_limits, out=torque)
        self._last_command = Command(reference.position, reference.velocity, torque)
        return self._last_command

    def _reference(self, now_ns: int) -> ReferenceSample:
        t = (now_ns - self._phase_start_ns) / 1e9
        if self._hold_request:
            self._hold_request = False
            if self.state in (State.RAMP_IN, State.PLAYING):
                current = self._ramp.sample(t) if self.state == State.RAMP_IN else self.trajectory.sample(t)
                self._hold = self._hold_at(current)
                self._enter(State.HOLDING, now_ns, "hold requested")
        if self.state == State.RAMP_IN:
            if t < self._ramp.duration:
                return self._ramp.sample(t)
            self._enter(State.PLAYING, now_ns, "ramp-in done")
            t = 0.0
        if self.state == State.PLAYING:
            if t < self.trajectory.duration:
                return self.trajectory.sample(t)
            self._hold = self._hold_at(self.trajectory.sample(self.trajectory.duration))
            self._enter(State.HOLDING, now_ns, "trajectory finished")
        return self._hold
