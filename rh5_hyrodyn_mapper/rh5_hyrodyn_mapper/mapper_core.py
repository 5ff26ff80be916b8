"""The mapper's two directions with their safety rules, free of ROS: used by the mapper node and the control cycle.

Joint commands become actuator setpoints through the closed-form inverse kinematics and f = J^-T tau,
clamped to the stroke, velocity and force limits (or refused, when clamping is off); actuator readings
become joint states through the warm-started forward kinematics and tau = J^T f. NaN/inf, wrong sizes
and singular poses are refused with the reason and never mapped. Counters and processing times are kept
for /diagnostics.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable

import numpy as np

from rh5_hyrodyn_mapper.kinematics.base import KinematicsError
from rh5_hyrodyn_mapper.mapping import ActuatorSample, JointSample, RobotMapper
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import ACTUATOR_NAMES
from rh5_msgs_py.realtime import LatencyWindow

JOINT_COMMANDS = "joint_commands"
ACTUATOR_STATES = "actuator_states"


def _finite(*arrays: FloatArray | None) -> bool:
    """Whether every value is finite: a sum is NaN or inf if any term is (one reduction per array)."""
    return all(x is None or math.isfinite(x.sum()) for x in arrays)


class MapperCore:
    """Joint commands -> actuator setpoints and actuator readings -> joint states, each with its refusals."""

    def __init__(
        self,
        mapper: RobotMapper,
        *,
        clamp_to_limits: bool = True,
        on_reject: Callable[[str, str], None] = lambda _topic, _reason: None,
    ) -> None:
        self.mapper = mapper
        self.clamp_to_limits = clamp_to_limits
        self._on_reject = on_reject
        self._last_q: FloatArray | None = None  # warm start of the forward kinematics
        self.rejected: Counter[str] = Counter()
        self.clamped: Counter[str] = Counter()
        self.latency = {JOINT_COMMANDS: LatencyWindow(), ACTUATOR_STATES: LatencyWindow()}

    def reject(self, topic: str, reason: str) -> None:
        """Count a refused input and report why."""
        self.rejected[topic] += 1
        self._on_reject(topic, reason)

    def to_actuator_command(
        self, q: FloatArray | None, v: FloatArray | None, tau: FloatArray | None
    ) -> ActuatorSample | None:
        """The actuator setpoints of a joint command within the limits, or None (refused, reason reported)."""
        start = time.perf_counter_ns()
        if q is None:
            self.reject(JOINT_COMMANDS, "no positions")
            return None
        if not _finite(q, v, tau):
            self.reject(JOINT_COMMANDS, "NaN or inf in the command")
            return None
        try:
            actuators = self.mapper.to_actuators(q, v, tau=tau)
        except (ValueError, KinematicsError) as err:  # wrong sizes, singular pose
            self.reject(JOINT_COMMANDS, str(err))
            return None
        if not _finite(actuators.position, actuators.velocity, actuators.effort):
            self.reject(JOINT_COMMANDS, "the pose maps to NaN or inf in actuator space")
            return None
        actuators, clamped = self.mapper.clamp(actuators)
        if clamped.any():
            names = [ACTUATOR_NAMES[i] for i in np.flatnonzero(clamped)]
            if not self.clamp_to_limits:
                self.reject(JOINT_COMMANDS, f"outside the actuator limits: {names}")
                return None
            self.clamped.update(names)
        self.latency[JOINT_COMMANDS].add(time.perf_counter_ns() - start)
        return actuators

    def to_joint_state(self, l: FloatArray | None, ld: FloatArray | None, f: FloatArray | None) -> JointSample | None:
        """The joint state of actuator readings, or None (refused, reason reported; the warm start is dropped)."""
        start = time.perf_counter_ns()
        if l is None or not _finite(l, ld, f):
            self.reject(ACTUATOR_STATES, "missing positions, NaN or inf")
            return None
        try:
            joints = self.mapper.to_joints(l, ld, f, q_guess=self._last_q)
        except (ValueError, KinematicsError) as err:  # wrong sizes, lengths that do not assemble
            self._last_q = None
            self.reject(ACTUATOR_STATES, str(err))
            return None
        self._last_q = joints.position
        self.latency[ACTUATOR_STATES].add(time.perf_counter_ns() - start)
        return joints
