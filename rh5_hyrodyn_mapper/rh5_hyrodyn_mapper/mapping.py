"""Whole-robot map between the 32 independent joints and the 32 actuator coordinates.

The assembly is block diagonal (HyRoDyn's explicit loop-closure maps): every submechanism
maps its own joints to its own actuators, and the rotary joints pass through unchanged.
Every call takes one sample (shape (32,)) or a whole trajectory (shape (N, 32)) and works
on all samples at once. Joint-space vectors are in names.JOINT_NAMES order, actuator-space
vectors in names.ACTUATOR_NAMES order.
"""

from __future__ import annotations

import functools
import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Final, NamedTuple

import numpy as np

from rh5_hyrodyn_mapper.kinematics import build_submechanisms
from rh5_hyrodyn_mapper.kinematics.base import FloatArray, KinematicsError, SubmechanismModel
from rh5_hyrodyn_mapper.kinematics.compiled import CompiledMaps
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


def _list_gather(sources: list[int]) -> Callable[[list[float]], list[float]] | None:
    """out[i] = values[sources[i]] on Python lists; None for the identity (the lists are then used in place)."""
    if sources == list(range(len(sources))):
        return None
    take = operator.itemgetter(*sources)
    return lambda values: list(take(values))


def _is_identity(model: SubmechanismModel) -> bool:
    """A pass-through unit (rotary joint, unit-ratio transmission), recognised by what it computes."""
    probe = np.linspace(-0.3, 0.4, model.dof)
    return bool(
        np.allclose(model.inverse(probe), probe, rtol=0, atol=1e-15)
        and np.allclose(model.jacobian(probe), np.eye(model.dof), rtol=0, atol=1e-15)
        and np.allclose(model.bias(probe, probe), 0.0, rtol=0, atol=1e-15)
    )


class RobotMapper:
    """The whole-robot joint <-> actuator map; immutable, built once from the submechanism models."""

    def __init__(
        self, submechanisms: tuple[SubmechanismModel, ...] | None = None, max_condition: float = DEFAULT_MAX_CONDITION
    ) -> None:
        self.submechanisms = build_submechanisms() if submechanisms is None else submechanisms
        self.max_condition = max_condition
        blocks, identity_joints, identity_actuators = [], [], []
        covered: list[int] = []
        for model in self.submechanisms:
            joints = [JOINT_INDEX[j] for j in model.joints]
            actuators = [ACTUATOR_INDEX[a] for a in model.actuators]
            covered.extend(joints)
            if _is_identity(model):
                identity_joints.extend(joints)
                identity_actuators.extend(actuators)
            else:
                blocks.append(_Block(model, _contiguous(joints, model.name), _contiguous(actuators, model.name)))
        self._blocks = tuple(blocks)
        self._identity_joints = np.array(identity_joints, dtype=np.intp)
        self._identity_actuators = np.array(identity_actuators, dtype=np.intp)
        if sorted(covered) != list(range(NUM_JOINTS)):
            msg = "the submechanisms do not cover every joint exactly once"
            raise ValueError(msg)
        # Single-sample path on Python lists: each block's fused float map; the pass-through values are gathered
        # once (index maps actuator <- joint and joint <- actuator). Block entries map to their own block's entries,
        # so on RH5 (same order on both sides) both maps are the identity and the input lists become the outputs.
        self._single_blocks = tuple(
            (b.model.to_actuator_space_floats, b.model.to_joint_space_floats, b.joints, b.actuators) for b in blocks
        )
        actuator_sources, joint_sources = list(range(NUM_ACTUATORS)), list(range(NUM_JOINTS))
        for joint, actuator in zip(identity_joints, identity_actuators, strict=True):
            actuator_sources[actuator], joint_sources[joint] = joint, actuator
        for b in blocks:  # their entries are overwritten by the block's results
            for joint, actuator in zip(
                range(b.joints.start, b.joints.stop), range(b.actuators.start, b.actuators.stop), strict=True
            ):
                actuator_sources[actuator], joint_sources[joint] = joint, actuator
        self._actuators_from_joints = _list_gather(actuator_sources)
        self._joints_from_actuators = _list_gather(joint_sources)
        # The control cycle's calls in C (None without the built extension): the float path is the fallback.
        self._compiled = CompiledMaps.build(
            [(b.model, b.joints.start, b.actuators.start) for b in blocks],
            list(zip(identity_joints, identity_actuators, strict=True)),
        )
        limits = {name: np.zeros(NUM_ACTUATORS) for name in ("length_min", "length_max", "velocity_max", "force_max")}
        for model in self.submechanisms:
            idx = [ACTUATOR_INDEX[a] for a in model.actuators]
            for name, values in limits.items():
                values[idx] = getattr(model.limits, name)
        for values in limits.values():
            values.setflags(write=False)
        self.length_min = limits["length_min"]
        self.length_max = limits["length_max"]
        self.velocity_max = limits["velocity_max"]
        self.force_max = limits["force_max"]

    @staticmethod
    def _shaped(values: FloatArray | None, what: str, size: int) -> FloatArray | None:
        if values is None:
            return None
        out = np.asarray(values, dtype=np.float64)
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
        if q.ndim == 1 and (v is None or v.ndim == 1) and (a is None or a.ndim == 1) and (tau is None or tau.ndim == 1):
            return self._to_actuators_single(q, v, a, tau)
        inputs = (q, v, a, tau)
        outputs = tuple(None if x is None else np.empty(q.shape) for x in inputs)
        for out, src in zip(outputs, inputs, strict=True):
            if out is not None:
                out[..., self._identity_actuators] = src[..., self._identity_joints]
        l, ld, ldd, f = outputs
        for block in self._blocks:
            jj = block.joints
            results = block.model.to_actuator_space(
                q[..., jj],
                None if v is None else v[..., jj],
                None if a is None else a[..., jj],
                None if tau is None else tau[..., jj],
                self.max_condition,
            )
            for out, result in zip(outputs, results, strict=True):
                if out is not None:
                    out[..., block.actuators] = result
        return ActuatorSample(l, ld, ldd, f)

    def _to_actuators_single(
        self, q: FloatArray, v: FloatArray | None, a: FloatArray | None, tau: FloatArray | None
    ) -> ActuatorSample:
        """``to_actuators`` for one sample (every input of shape (32,)): in C for the cycle's call (q, v, tau),
        else (or when a unit refuses: Python gives the reason) on Python lists, one array per output."""
        max_condition = self.max_condition
        if self._compiled is not None and v is not None and tau is not None and a is None:
            mapped = self._compiled.to_actuators(q, v, tau, max_condition)
            if mapped is not None:
                return ActuatorSample(mapped[0], mapped[1], None, mapped[2])
        qs = q.tolist()
        vs = None if v is None else v.tolist()
        acc = None if a is None else a.tolist()
        ts = None if tau is None else tau.tolist()
        gather = self._actuators_from_joints
        if gather is None:  # outputs overwrite the inputs' lists block by block (each block reads its slice first)
            l, ld, ldd, f = qs, vs, acc, ts
        else:
            l = gather(qs)
            ld = None if vs is None else gather(vs)
            ldd = None if acc is None else gather(acc)
            f = None if ts is None else gather(ts)
        blocks = self._single_blocks
        if vs is not None and ts is not None:  # the common calls: (q, v, tau) and (q, v, a, tau)
            if acc is None:
                for fused, _, jj, aa in blocks:
                    l[aa], ld[aa], _, f[aa] = fused(qs[jj], vs[jj], None, ts[jj], max_condition)
            else:
                for fused, _, jj, aa in blocks:
                    l[aa], ld[aa], ldd[aa], f[aa] = fused(qs[jj], vs[jj], acc[jj], ts[jj], max_condition)
        else:
            for fused, _, jj, aa in blocks:
                rl, rld, rldd, rf = fused(
                    qs[jj],
                    None if vs is None else vs[jj],
                    None if acc is None else acc[jj],
                    None if ts is None else ts[jj],
                    max_condition,
                )
                l[aa] = rl
                if ld is not None:
                    ld[aa] = rld
                    if ldd is not None:
                        ldd[aa] = rldd
                if f is not None:
                    f[aa] = rf
        return ActuatorSample(
            _vector(l, NUM_ACTUATORS),
            _vector(ld, NUM_ACTUATORS),
            _vector(ldd, NUM_ACTUATORS),
            _vector(f, NUM_ACTUATORS),
        )

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
        if (
            l.ndim == 1
            and (ld is None or ld.ndim == 1)
            and (f is None or f.ndim == 1)
            and (q_guess is None or q_guess.ndim == 1)
        ):
            return self._to_joints_single(l, ld, f, q_guess)
        inputs = (l, ld, f)
        outputs = tuple(None if x is None else np.empty(l.shape) for x in inputs)
        for out, src in zip(outputs, inputs, strict=True):
            if out is not None:
                out[..., self._identity_joints] = src[..., self._identity_actuators]
        for block in self._blocks:
            aa = block.actuators
            results = block.model.to_joint_space(
                l[..., aa],
                None if ld is None else ld[..., aa],
                None if f is None else f[..., aa],
                None if q_guess is None else q_guess[..., block.joints],
            )
            for out, result in zip(outputs, results, strict=True):
                if out is not None:
                    out[..., block.joints] = result
        q, v, tau = outputs
        return JointSample(q, v, None, tau)

    def _to_joints_single(
        self, l: FloatArray, ld: FloatArray | None, f: FloatArray | None, q_guess: FloatArray | None
    ) -> JointSample:
        """``to_joints`` for one sample (every input of shape (32,)): in C for the cycle's call (l, l_dot, f and a
        warm start), else (or when a unit refuses) on Python lists, one array per output."""
        if self._compiled is not None and ld is not None and f is not None and q_guess is not None:
            mapped = self._compiled.to_joints(l, ld, f, q_guess)
            if mapped is not None:
                return JointSample(mapped[0], mapped[1], None, mapped[2])
        ls = l.tolist()
        lds = None if ld is None else ld.tolist()
        fs = None if f is None else f.tolist()
        guess = None if q_guess is None else q_guess.tolist()
        gather = self._joints_from_actuators
        if gather is None:  # outputs overwrite the inputs' lists block by block (each block reads its slice first)
            q, v, tau = ls, lds, fs
        else:
            q = gather(ls)
            v = None if lds is None else gather(lds)
            tau = None if fs is None else gather(fs)
        blocks = self._single_blocks
        if lds is not None and fs is not None and guess is not None:  # the node's call
            for _, fused, jj, aa in blocks:
                q[jj], v[jj], tau[jj] = fused(ls[aa], lds[aa], fs[aa], guess[jj])
        else:
            for _, fused, jj, aa in blocks:
                rq, rv, rtau = fused(
                    ls[aa],
                    None if lds is None else lds[aa],
                    None if fs is None else fs[aa],
                    None if guess is None else guess[jj],
                )
                q[jj] = rq
                if v is not None:
                    v[jj] = rv
                if tau is not None:
                    tau[jj] = rtau
        return JointSample(_vector(q, NUM_JOINTS), _vector(v, NUM_JOINTS), None, _vector(tau, NUM_JOINTS))

    def limit_report(self, actuators: ActuatorSample) -> LimitReport:
        """Stroke, velocity and force utilisation of every actuator at every sample, and every violation."""
        l = np.atleast_2d(actuators.position)
        n = l.shape[0]
        half = 0.5 * (self.length_max - self.length_min)
        stroke = np.abs(l - 0.5 * (self.length_max + self.length_min)) / half
        velocity = (
            np.zeros((n, NUM_ACTUATORS))
            if actuators.velocity is None
            else np.abs(np.atleast_2d(actuators.velocity)) / self.velocity_max
        )
        force = (
            np.zeros((n, NUM_ACTUATORS))
            if actuators.effort is None
            else np.abs(np.atleast_2d(actuators.effort)) / self.force_max
        )
        violations: list[Violation] = []
        checks = (
            ("stroke", stroke, l, np.where(l > self.length_max, self.length_max, self.length_min)),
            ("velocity", velocity, actuators.velocity, self.velocity_max),
            ("force", force, actuators.effort, self.force_max),
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
        """Clamp setpoints to the stroke, velocity and force limits; also say which actuators were clamped."""
        l = np.clip(actuators.position, self.length_min, self.length_max)
        clamped = l != actuators.position
        ld, f = actuators.velocity, actuators.effort
        if ld is not None:
            ld_clamped = np.clip(ld, -self.velocity_max, self.velocity_max)
            clamped |= ld_clamped != ld
            ld = ld_clamped
        if f is not None:
            f_clamped = np.clip(f, -self.force_max, self.force_max)
            clamped |= f_clamped != f
            f = f_clamped
        return ActuatorSample(l, ld, actuators.acceleration, f), clamped


def _vector(values: Sequence[float] | None, size: int) -> FloatArray | None:
    """The float64 array of one sample's list (None stays None); a block that returned a wrong count shows here."""
    if values is None:
        return None
    if len(values) != size:
        msg = f"a submechanism returned a wrong number of values ({len(values)} instead of {size} in all)"
        raise ValueError(msg)
    return np.array(values, dtype=np.float64)


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
