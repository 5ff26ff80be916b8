"""Whole-robot map between the 32 independent joints and the 32 actuator coordinates.

The assembly is block diagonal (HyRoDyn's explicit loop-closure maps): every submechanism
maps its own joints to its own actuators, and the rotary joints pass through unchanged.
Every call takes one sample (shape (32,)) or a whole trajectory (shape (N, 32)): one C call
over the table of every unit (kinematics/kernels.py), so the 1 kHz cycle's sample is a batch
of one through the same code. Joint-space vectors are in names.JOINT_NAMES order,
actuator-space vectors in names.ACTUATOR_NAMES order.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, NamedTuple

import numpy as np

from rh5_hyrodyn_mapper.kinematics import build_submechanisms, kernels
from rh5_hyrodyn_mapper.kinematics.base import KinematicsError, SubmechanismModel, actuator_limits, common_samples
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import ACTUATOR_INDEX, ACTUATOR_NAMES, JOINT_INDEX, NUM_ACTUATORS, NUM_JOINTS

DEFAULT_MAX_CONDITION: Final = 1e6


class ActuatorSample(NamedTuple):
    """Actuator space: lengths [m] or angles [rad], their rates, accelerations, forces [N] or torques [Nm]."""

    position: FloatArray
    velocity: FloatArray | None = None
    acceleration: FloatArray | None = None
    effort: FloatArray | None = None


class JointSample(NamedTuple):
    """Joint space of the serial tree: angles [rad], rates, accelerations, torques [Nm]."""

    position: FloatArray
    velocity: FloatArray | None = None
    acceleration: FloatArray | None = None
    effort: FloatArray | None = None


@dataclass(frozen=True)
class Violation:
    """One actuator limit exceeded at one sample."""

    sample: int
    actuator: str
    kind: str  # "stroke", "velocity" or "force"
    value: float
    limit: float


@dataclass(frozen=True)
class LimitReport:
    """Utilisation of every actuator limit at every sample (1.0 = at the limit) and the violations."""

    stroke: FloatArray  # (N, 32): 0 at mid-stroke, 1 at either end
    velocity: FloatArray  # (N, 32): |l_dot| / v_max
    force: FloatArray  # (N, 32): |f| / f_max
    violations: tuple[Violation, ...] = field(default=())

    @property
    def ok(self) -> bool:
        """Whether every limit holds at every sample."""
        return not self.violations

    def peak(self) -> dict[str, dict[str, float]]:
        """Highest utilisation per actuator and limit kind, for tables and plots."""
        return {
            name: {
                "stroke": float(self.stroke[:, i].max(initial=0.0)),
                "velocity": float(self.velocity[:, i].max(initial=0.0)),
                "force": float(self.force[:, i].max(initial=0.0)),
            }
            for i, name in enumerate(ACTUATOR_NAMES)
        }


@dataclass(frozen=True)
class _Block:
    """A submechanism and where its joints and actuators sit in the whole-robot vectors (contiguous)."""

    model: SubmechanismModel
    joints: slice
    actuators: slice


def _contiguous(indices: list[int], what: str) -> slice:
    """The slice covering ``indices``, which must be consecutive (names.SUBMECHANISMS guarantees it)."""
    if indices != list(range(indices[0], indices[0] + len(indices))):
        msg = f"{what}: indices {indices} are not consecutive"
        raise ValueError(msg)
    return slice(indices[0], indices[0] + len(indices))


class RobotMapper:
    """The whole-robot joint <-> actuator map; immutable, built once from the submechanism models."""

    def __init__(
        self, submechanisms: tuple[SubmechanismModel, ...] | None = None, max_condition: float = DEFAULT_MAX_CONDITION
    ) -> None:
        self.submechanisms = build_submechanisms() if submechanisms is None else submechanisms
        self.max_condition = max_condition
        blocks = []
        covered: list[int] = []
        for model in self.submechanisms:
            joints = [JOINT_INDEX[j] for j in model.joints]
            actuators = [ACTUATOR_INDEX[a] for a in model.actuators]
            covered.extend(joints)
            blocks.append(_Block(model, _contiguous(joints, model.name), _contiguous(actuators, model.name)))
        if sorted(covered) != list(range(NUM_JOINTS)):
            msg = "the submechanisms do not cover every joint exactly once"
            raise ValueError(msg)
        self._blocks = tuple(blocks)
        self._table = kernels.table([b.model.kernel_row(b.joints.start, b.actuators.start) for b in blocks])
        limits = {name: np.zeros(NUM_ACTUATORS) for name in ("length_min", "length_max", "velocity_max", "force_max")}
        for model in self.submechanisms:
            idx = [ACTUATOR_INDEX[a] for a in model.actuators]
            for name, values in limits.items():
                values[idx] = getattr(model.limits, name)
        self.limits = actuator_limits(**limits)
        """Every actuator's stroke, speed and force limits (ACTUATOR_NAMES order), from its submechanism."""

    @staticmethod
    def _shaped(values: FloatArray | None, what: str, size: int) -> FloatArray | None:
        if values is None:
            return None
        out = np.ascontiguousarray(values, dtype=np.float64)  # as the kernels read it
        shape = out.shape
        if not shape or shape[-1] != size:
            msg = f"{what}: expected {size} values per sample, got shape {out.shape}"
            raise ValueError(msg)
        return out

    def to_actuators(
        self,
        q: FloatArray,
        v: FloatArray | None = None,
        a: FloatArray | None = None,
        tau: FloatArray | None = None,
    ) -> ActuatorSample:
        """Map joint positions (and optionally velocities, accelerations, torques) to actuator space.

        Accelerations need velocities (for the bias term J-dot q-dot). Raises SingularityError
        (a KinematicsError) when a force map is asked for near a singular pose.
        """
        shaped = self._shaped
        q = shaped(q, "q", NUM_JOINTS)
        v = None if v is None else shaped(v, "v", NUM_JOINTS)
        a = None if a is None else shaped(a, "a", NUM_JOINTS)
        tau = None if tau is None else shaped(tau, "tau", NUM_JOINTS)
        if a is not None and v is None:
            msg = "accelerations need velocities (the bias term J-dot q-dot depends on them)"
            raise ValueError(msg)
        shape = q.shape
        if (
            (v is not None and v.shape != shape)
            or (a is not None and a.shape != shape)
            or (tau is not None and tau.shape != shape)
        ):
            shape, _, (q, v, a, tau) = common_samples((q, v, a, tau))
        n = q.size // NUM_JOINTS
        l = np.empty(shape)
        ld = None if v is None else np.empty(shape)
        ldd = None if a is None else np.empty(shape)
        f = None if tau is None else np.empty(shape)
        if n and kernels.ik(self._table, n, q, v, a, tau, self.max_condition, l, ld, ldd, f, None) >= 0:
            self._explain((q, v, a, tau), "ik")
        return ActuatorSample(l, ld, ldd, f)

    def to_joints(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        q_guess: FloatArray | None = None,
    ) -> JointSample:
        """Map actuator readings (positions, optionally rates and forces) back to joint states.

        ``q_guess`` warm-starts the Newton forward kinematics of the 2-DOF units (the previous
        sample's joints at 1 kHz); without it they start cold. Raises ForwardKinematicsError.
        """
        shaped = self._shaped
        l = shaped(l, "l", NUM_ACTUATORS)
        ld = None if ld is None else shaped(ld, "ld", NUM_ACTUATORS)
        f = None if f is None else shaped(f, "f", NUM_ACTUATORS)
        q_guess = None if q_guess is None else shaped(q_guess, "q_guess", NUM_JOINTS)
        shape = l.shape
        if (
            (ld is not None and ld.shape != shape)
            or (f is not None and f.shape != shape)
            or (q_guess is not None and q_guess.shape != shape)
        ):
            shape, _, (l, ld, f, q_guess) = common_samples((l, ld, f, q_guess))
        n = l.size // NUM_ACTUATORS
        q = np.empty(shape)
        v = None if ld is None else np.empty(shape)
        tau = None if f is None else np.empty(shape)
        if n and kernels.fk(self._table, n, l, ld, f, q_guess, q, v, tau, None) >= 0:
            self._explain((l, ld, f, q_guess), "fk")
        return JointSample(q, v, None, tau)

    def _explain(self, inputs: Sequence[FloatArray | None], direction: str) -> None:
        """Raise the failing unit's own error: its model maps its slice of the inputs again and says why."""
        for block in self._blocks:
            jj, aa = block.joints, block.actuators
            if direction == "ik":
                slices = [None if x is None else x[..., jj] for x in inputs]
                block.model.to_actuator_space(*slices, self.max_condition)
            else:
                slices = [None if x is None else x[..., aa] for x in inputs[:3]]
                guess = inputs[3]
                block.model.to_joint_space(*slices, None if guess is None else guess[..., jj])
        msg = f"the mapper's {direction} kernel refused a sample that no unit refuses alone"
        raise KinematicsError(msg)

    def limit_report(self, actuators: ActuatorSample) -> LimitReport:
        """Stroke, velocity and force utilisation of every actuator at every sample, and every violation."""
        lim = self.limits
        l = np.atleast_2d(actuators.position)
        n = l.shape[0]
        half = 0.5 * (lim.length_max - lim.length_min)
        stroke = np.abs(l - 0.5 * (lim.length_max + lim.length_min)) / half
        velocity = (
            np.zeros((n, NUM_ACTUATORS))
            if actuators.velocity is None
            else np.abs(np.atleast_2d(actuators.velocity)) / lim.velocity_max
        )
        force = (
            np.zeros((n, NUM_ACTUATORS))
            if actuators.effort is None
            else np.abs(np.atleast_2d(actuators.effort)) / lim.force_max
        )
        violations: list[Violation] = []
        checks = (
            ("stroke", stroke, l, np.where(l > lim.length_max, lim.length_max, lim.length_min)),
            ("velocity", velocity, actuators.velocity, lim.velocity_max),
            ("force", force, actuators.effort, lim.force_max),
        )
        for kind, utilisation, raw_values, raw_limit in checks:
            if raw_values is None:
                continue
            values = np.atleast_2d(raw_values)
            limit = np.broadcast_to(raw_limit, values.shape)
            violations.extend(
                Violation(int(k), ACTUATOR_NAMES[i], kind, float(values[k, i]), float(limit[k, i]))
                for k, i in zip(*np.nonzero(utilisation > 1.0), strict=True)
            )
        violations.sort(key=lambda x: (x.sample, x.actuator, x.kind))
        return LimitReport(stroke, velocity, force, tuple(violations))

    def clamp(self, actuators: ActuatorSample) -> tuple[ActuatorSample, np.ndarray]:
        """Setpoints clamped to the stroke, velocity and force limits (``ActuatorLimits.clamp``), and which
        actuators were clamped. A missing velocity or force stays missing."""
        position, velocity, effort = actuators.position, actuators.velocity, actuators.effort
        if velocity is None or effort is None:
            zeros = np.zeros_like(position)  # inside every range: never clamped
            rows = np.array([position, zeros if velocity is None else velocity, zeros if effort is None else effort])
        else:
            rows = np.array([position, velocity, effort])
        (position, clamped_velocity, clamped_effort), clamped = self.limits.clamp(rows)
        return (
            ActuatorSample(
                position,
                None if velocity is None else clamped_velocity,
                actuators.acceleration,
                None if effort is None else clamped_effort,
            ),
            clamped,
        )


@functools.cache
def robot_mapper() -> RobotMapper:
    """The process-wide mapper of the RH5 model (built on first use)."""
    return RobotMapper()


__all__ = [
    "ActuatorSample",
    "JointSample",
    "KinematicsError",
    "LimitReport",
    "RobotMapper",
    "Violation",
    "robot_mapper",
]
