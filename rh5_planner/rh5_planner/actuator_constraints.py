"""The actuator limits inside the shooting problem: per-knot bounds that Crocoddyl evaluates in C++.

:class:`ActuatorConstraints` owns, for every node of a built problem, the joint-limit barrier's
``ActivationModelQuadraticBarrier`` (a ``ResidualModelState`` whose bounds are the joint limits) and, for the
running contact nodes, Box-FDDP's control box. :meth:`~ActuatorConstraints.refresh` intersects the joint limits
with the actuator boxes of :class:`rh5_planner.actuator_bounds.ActuatorBounds`, built at the current iterate, and
writes them into those C++ objects; the solver calls it before every continuation stage. So the per-knot work
of an iteration stays Crocoddyl's own: the same residual and activation as without actuator limits, only with
other numbers in their bounds.

:meth:`~ActuatorConstraints.check` measures the exact actuator stroke, velocity and force (the mapper's maps) at
the knots and along the 1 kHz interpolation the planner publishes (:func:`rh5_planner.interpolation.interpolate`),
and :meth:`~ActuatorConstraints.tighten_from` lowers the bounds around what it found over a limit (the linearised
bounds of the last refresh, the soft barrier's overshoot or the spline between knots), for another refresh and
re-solve.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import crocoddyl
import numpy as np
import numpy.typing as npt

from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import ACTUATOR_INDEX, NUM_JOINTS
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData

from .actuator_bounds import ACTUATOR_LIMIT_KINDS, ActuatorBounds, parallel_units
from .interpolation import interpolate

__all__ = ["LINEAR_ACTUATORS", "ActuatorCheck", "ActuatorConstraints", "actuator_usage", "check_trajectory"]

LINEAR_ACTUATORS: Final[tuple[str, ...]] = tuple(a for m in parallel_units() for a in m.actuators)
"""The 14 linear actuators of Table I (parallel submechanisms), in names.ACTUATOR_NAMES order."""
_ACT_IDX: Final = np.array([ACTUATOR_INDEX[a] for a in LINEAR_ACTUATORS], dtype=np.intp)
_UNIT_OF_ACTUATOR: Final = {a: m for m in parallel_units() for a in m.actuators}


def actuator_usage(
    q: FloatArray, v: FloatArray, tau: FloatArray | None, factors: Mapping[str, FloatArray] | None = None
) -> dict[str, FloatArray]:
    """Exact utilisation (1 = at the limit) of the 14 linear actuators: stroke (0 mid-stroke, 1 at either end),
    |velocity| / v_max and |force| / f_max, each (N, 14) (force: len(tau) rows), for joint samples in JOINT_NAMES
    order. ``factors`` (kind -> (32,) per joint) scale the limits as the design heuristic plans with them."""
    mapper = robot_mapper()
    sample = mapper.to_actuators(q, v)
    lo, hi = mapper.limits.length_min[_ACT_IDX], mapper.limits.length_max[_ACT_IDX]
    scale = {k: _actuator_factors(factors, k) for k in ACTUATOR_LIMIT_KINDS}
    out = {
        "stroke": np.abs(sample.position[:, _ACT_IDX] - 0.5 * (lo + hi)) / (0.5 * (hi - lo) * scale["stroke"]),
        "velocity": np.abs(sample.velocity[:, _ACT_IDX]) / (mapper.limits.velocity_max[_ACT_IDX] * scale["velocity"]),
    }
    if tau is not None:
        force = mapper.to_actuators(q[: len(tau)], None, None, tau).effort
        out["force"] = np.abs(force[:, _ACT_IDX]) / (mapper.limits.force_max[_ACT_IDX] * scale["force"])
    return out


def _actuator_factors(factors: Mapping[str, FloatArray] | None, kind: str) -> FloatArray:
    """(14,) factor per linear actuator: the largest of its unit's joints' (one actuator type per unit)."""
    if factors is None or kind not in factors:
        return np.ones(len(LINEAR_ACTUATORS))
    from rh5_msgs_py.names import JOINT_INDEX  # noqa: PLC0415

    per_joint = np.asarray(factors[kind], dtype=float)
    return np.array([max(per_joint[JOINT_INDEX[j]] for j in _UNIT_OF_ACTUATOR[a].joints) for a in LINEAR_ACTUATORS])


@dataclass(frozen=True)
class ActuatorCheck:
    """Peak utilisation per kind at the knots and at 1 kHz, and what is over the limit.

    ``over`` lists (kind, knot, actuator, usage) with ``knot`` the kept knot (trajectory file row) at or before
    the sample."""

    knots: Mapping[str, FloatArray]
    """kind -> (14,) peak utilisation over the knots."""
    samples: Mapping[str, FloatArray]
    """kind -> (14,) peak utilisation over the 1 kHz samples."""
    over: Sequence[tuple[str, int, str, float]] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        """Whether every enforced limit holds at every knot and sample."""
        return not self.over

    def summary(self) -> dict[str, Any]:
        """JSON-able peaks: kind -> {knots: [actuator, usage], 1khz: [actuator, usage]}."""
        out: dict[str, Any] = {}
        for kind in self.knots:
            k, s = self.knots[kind], self.samples[kind]
            out[kind] = {
                "knots": [LINEAR_ACTUATORS[int(np.argmax(k))], round(float(k.max()), 4)],
                "1khz": [LINEAR_ACTUATORS[int(np.argmax(s))], round(float(s.max()), 4)],
            }
        return out


def check_trajectory(
    data: TrajectoryData,
    kinds: Sequence[str] = ACTUATOR_LIMIT_KINDS,
    factors: Mapping[str, FloatArray] | None = None,
    tolerance: float = 1e-6,
) -> ActuatorCheck:
    """Exact utilisation of the 14 linear actuators at the knots of ``data`` and along its 1 kHz interpolation
    (:func:`rh5_planner.interpolation.interpolate`, what the planner publishes); what exceeds 1 + ``tolerance``."""
    q, v = data.joint_positions(), data.joint_velocities()
    knots = actuator_usage(q, v, np.asarray(data.controls), factors)
    fine = interpolate(data, joints_only=True)
    samples = actuator_usage(fine.states[:, 7:NQ], fine.states[:, NQ + 6 :], fine.controls, factors)
    segment = np.clip(np.searchsorted(data.times, fine.times + 1e-9, side="right") - 1, 0, len(data.times) - 1)
    over: list[tuple[str, int, str, float]] = []
    for kind in kinds:
        for usage, rows in ((knots[kind], np.arange(len(knots[kind]))), (samples[kind], segment)):
            hit = np.argwhere(usage > 1.0 + tolerance)
            over.extend((kind, int(rows[r]), LINEAR_ACTUATORS[a], float(usage[r, a])) for r, a in hit)
    peak_k = {k: knots[k].max(axis=0) for k in kinds}
    peak_s = {k: samples[k].max(axis=0) for k in kinds}
    return ActuatorCheck(peak_k, peak_s, tuple(over))


class ActuatorConstraints:
    """Per-node actuator bounds of one shooting problem (see the module docstring).

    ``barriers[i]`` is node i's joint-limit activation (None: node without it), ``controls[i]`` node i's action
    model if it has a control box (running contact nodes), ``joint_lb``/``joint_ub`` the joint-limit barrier's own
    bounds (tangent-space state order), ``tau_max`` the joint torque box (pinocchio v order without the base).
    ``q_order``/``v_order`` map JOINT_NAMES to pinocchio q / v indices (``q_index``/``v_index`` of the model).
    ``kept`` are the node indices that become the trajectory's knots (pre-impact nodes dropped).
    """

    def __init__(
        self,
        bounds: ActuatorBounds,
        *,
        barriers: Sequence[Any],
        controls: Sequence[Any],
        joint_lb: FloatArray,
        joint_ub: FloatArray,
        tau_max: FloatArray,
        q_order: npt.NDArray[np.intp],
        v_order: npt.NDArray[np.intp],
        kept: Sequence[int],
        nq: int,
    ) -> None:
        self.bounds = bounds
        self.barriers = list(barriers)
        self.controls = list(controls)
        self.joint_lb, self.joint_ub = np.asarray(joint_lb), np.asarray(joint_ub)
        self.tau_max = np.asarray(tau_max)
        self.q_order, self.v_order = np.asarray(q_order), np.asarray(v_order)
        self.kept = list(kept)
        self.nq = nq
        self.refreshes = 0
        self.overhead_s = 0.0
        """CPU time spent here (refreshes and checks): the Python part of the actuator limits."""

    @property
    def kinds(self) -> tuple[str, ...]:
        """The enforced limit kinds."""
        return self.bounds.kinds

    def _joint_arrays(self, xs: Sequence[FloatArray], us: Sequence[FloatArray]) -> tuple[FloatArray, ...]:
        """q, v (nodes, 32) and tau (nodes - 1, 32; zero for nodes without control) in JOINT_NAMES order."""
        x = np.asarray([np.asarray(xi) for xi in xs])
        q = x[:, self.q_order]
        v = x[:, self.nq + self.v_order]
        tau = np.zeros((len(us), NUM_JOINTS))
        for i, control in enumerate(us):
            u = np.asarray(control)
            if u.size:
                tau[i] = u[self.v_order - 6]
        return q, v, tau

    def refresh(self, xs: Sequence[FloatArray], us: Sequence[FloatArray]) -> None:
        """Rebuild every node's bounds at the iterate (xs, us) and write them into the problem's models."""
        start = time.process_time()
        q, v, tau = self._joint_arrays(xs, us)
        boxes = self.bounds.boxes(q, v, tau)
        nq_t = self.nq - 1  # tangent rows of the configuration (free flyer: 6 for 7)
        q_rows, v_rows = self.q_order - 1, nq_t + self.v_order
        for i, activation in enumerate(self.barriers):
            if activation is None:
                continue
            lb, ub = self.joint_lb.copy(), self.joint_ub.copy()
            lb[q_rows] = np.maximum(lb[q_rows], boxes.q_lower[i])
            ub[q_rows] = np.minimum(ub[q_rows], boxes.q_upper[i])
            lb[v_rows] = np.maximum(lb[v_rows], -boxes.v_max[i])
            ub[v_rows] = np.minimum(ub[v_rows], boxes.v_max[i])
            activation.bounds = crocoddyl.ActivationBounds(lb, np.maximum(lb, ub), 1.0)
        order = self.v_order - 6
        for i, model in enumerate(self.controls):
            if model is None or i >= len(tau):
                continue
            limit = self.tau_max.copy()
            limit[order] = np.minimum(limit[order], boxes.tau_max[i])
            model.u_lb = -limit
            model.u_ub = limit
        self.refreshes += 1
        self.overhead_s += time.process_time() - start

    def check(self, data: TrajectoryData, tolerance: float = 1e-6) -> ActuatorCheck:
        """Exact utilisation at the knots of ``data`` and at 1 kHz against the limits planned with."""
        return check_trajectory(data, self.kinds, self.bounds.factors, tolerance)

    def check_iterate(
        self, xs: Sequence[FloatArray], us: Sequence[FloatArray], dt: float, tolerance: float = 1e-6
    ) -> ActuatorCheck:
        """:meth:`check` of the solver's iterate itself (the kept nodes as knots ``dt`` apart, joints only, no
        contact data): what the trajectory file will hold, without a pass over the problem to extract it."""
        start = time.process_time()
        q, v, tau = self._joint_arrays(xs, us)
        kept = np.asarray(self.kept)
        n = kept.size
        states = np.zeros((n, NQ + 6 + NUM_JOINTS))
        states[:, 6] = 1.0  # identity base orientation: the joints alone are checked
        states[:, 7:NQ] = q[kept]
        states[:, NQ + 6 :] = v[kept]
        data = TrajectoryData(
            times=dt * np.arange(n),
            states=states,
            controls=tau[kept[:-1]],
            contact_wrenches=np.zeros((n, 2, 6)),
            contact_phases=np.zeros((n, 2), dtype=bool),
            cop=np.full((n, 2, 2), np.nan),
            motion={"name": "check"},
            model_hash="check",
        )
        check = self.check(data, tolerance)
        self.overhead_s += time.process_time() - start
        return check

    def tighten_from(self, check: ActuatorCheck, margin: float = 0.97) -> int:
        """Lower the bounds of every (kind, unit) over its limit, at the node of its knot and the next one, by
        ``margin`` / usage (the worst usage per node and unit); returns how many node-unit bounds changed."""
        from rh5_msgs_py.names import JOINT_INDEX  # noqa: PLC0415

        worst: dict[tuple[str, int, str], float] = {}
        for kind, knot, actuator, usage in check.over:
            unit = _UNIT_OF_ACTUATOR[actuator].name
            for k in (knot, knot + 1):
                if k < len(self.kept):
                    key = (kind, self.kept[k], unit)
                    worst[key] = max(worst.get(key, 0.0), usage)
        units = {m.name: m for m in parallel_units()}
        for (kind, node, unit), usage in worst.items():
            joints = [JOINT_INDEX[j] for j in units[unit].joints]
            self.bounds.tighten(kind, [node], joints, margin / usage)
        return len(worst)
