"""The linear actuators' limits (paper, Table I: stroke, velocity, force) as per-knot boxes in joint space.

A parallel submechanism (Hip3 and knee 1-RRPR, ankle 2-SPRR+1U, torso and wrist 2-SPU+1U) with joints y and
actuator lengths l(y) has J(y) = dl/dy (rh5_hyrodyn_mapper's exact maps), actuator velocity J(y) y_dot and
actuator force f = J(y)^-T tau. Its limits

    l_min <= l(y) <= l_max,   |J(y) y_dot| <= v_max,   |J(y)^-T tau| <= f_max   (row-wise)

become boxes on the joint position, velocity and torque of every knot, built at the configuration of the
current iterate (q_bar, v_bar, tau_bar) so that Crocoddyl evaluates them in C++ (the joint-limit
``ResidualModelState`` with its ``ActivationModelQuadraticBarrier``, and Box-FDDP's control box); the problem
builder refreshes them between continuation stages (:mod:`rh5_planner.ocp`):

* 1-DoF units (Hip3, knees): exact. The stroke is a fixed joint interval (l is monotonic over the joint range;
  found on a fine grid), the velocity bound is v_max / |J(q_bar)| and the torque bound f_max |J(q_bar)|.
* 2-DoF units: a row-wise bound |A x| <= c (A = J for velocities, J^-T for torques) is a parallelogram in the
  joint plane. The box with half-widths a_j = s w_j c_j, c_j = c / max_i |A_ij| (each joint alone at the limit)
  and s the largest scale with sum_j |A_ij| a_j <= c for every row, lies inside it with a corner on its boundary.
  The weights w_j = max(|x_bar_j| / c_j, floor) give the joint the iterate uses more the larger share, so the
  box sits where the optimum is heading. The stroke is linearised about q_bar: each actuator's slack to either
  end of its stroke is shared between the joints in the same way (weights 1), at knots whose iterate uses more
  than ``stroke_activation`` of a half-stroke (elsewhere the shared slack would only restrict joints far from
  any stroke end; the exact check after the solve catches the rest).

Every bound is shrunk by its ``beta`` (costs.yaml ``actuator_limits``) so that the soft barrier's overshoot,
the linearisation between refreshes and the 1 kHz spline between knots stay inside the true limits, and scaled
per actuator and kind by the design heuristic's factors. :meth:`ActuatorBounds.tighten` lowers the factor of
chosen knots and joints further where the exact check (knots and 1 kHz) still found a violation.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from rh5_hyrodyn_mapper.kinematics import build_submechanisms
from rh5_hyrodyn_mapper.kinematics.base import SubmechanismModel
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_INDEX, NUM_JOINTS

__all__ = ["ACTUATOR_LIMIT_KINDS", "PARALLEL_KINDS", "ActuatorBounds", "JointBoxes", "parallel_units"]

ACTUATOR_LIMIT_KINDS: Final = ("stroke", "velocity", "force")
"""The actuator limits of Table I, in the names of costs.yaml ``actuator_limits.kinds``."""
PARALLEL_KINDS: Final = ("1-RRPR", "2-SPRR+1U", "2-SPU+1U")
"""Submechanism kinds with linear actuators of their own (the head transmission and rotary joints have none)."""
_GRID: Final = 4001


def parallel_units() -> tuple[SubmechanismModel, ...]:
    """The parallel submechanism models (14 linear actuators), in names.SUBMECHANISMS order."""
    return tuple(m for m in build_submechanisms() if m.kind in PARALLEL_KINDS)


@dataclass(frozen=True)
class JointBoxes:
    """Per-knot joint-space boxes, (N, 32) each in JOINT_NAMES order; +-inf where a joint has no actuator bound."""

    q_lower: FloatArray
    q_upper: FloatArray
    v_max: FloatArray
    tau_max: FloatArray


def _share_box(a: FloatArray, limit: float, usage: FloatArray, floor: float) -> FloatArray:
    """Half-widths (N, m) of the box inside {x : |A x|_i <= limit} weighted by ``usage`` (N, m) of the iterate.

    ``a`` is (N, m, m). Returns inf for joints no row of A touches (a zero column)."""
    col = np.abs(a).max(axis=1)  # (N, m): max_i |A_ij|
    with np.errstate(divide="ignore"):
        alone = np.where(col > 0, limit / col, np.inf)  # each joint alone at the limit
    weight = np.maximum(np.where(np.isfinite(alone), usage / alone, 0.0), floor)
    finite_alone = np.where(np.isfinite(alone), alone, 0.0)
    load = np.einsum("nij,nj->ni", np.abs(a), weight * finite_alone)  # (N, m): row sums at scale 1
    scale = limit / np.maximum(load.max(axis=1), 1e-300)
    return np.where(np.isfinite(alone), scale[:, None] * weight * finite_alone, np.inf)


@dataclass(frozen=True)
class _Unit:
    model: SubmechanismModel
    joints: npt.NDArray[np.intp]
    stroke_interval: tuple[float, float] | None  # 1-DoF: the joint interval inside the (scaled) stroke


class ActuatorBounds:
    """Turns the parallel mechanisms' actuator limits into per-knot joint boxes at an iterate (JOINT_NAMES order).

    ``settings`` is costs.yaml ``actuator_limits`` (kinds, stroke_beta, velocity_beta, force_beta, share_floor,
    stroke_activation);
    ``factors`` maps a kind (stroke, velocity, force) to (32,) per-joint factors (design heuristic; a stroke
    factor widens the stroke about its middle). ``knots`` is the number of nodes the boxes are built for.
    """

    def __init__(self, settings: Mapping[str, Any], knots: int, factors: Mapping[str, FloatArray] | None = None):
        kinds = tuple(settings.get("kinds", ACTUATOR_LIMIT_KINDS))
        unknown = sorted(set(kinds) - set(ACTUATOR_LIMIT_KINDS))
        if unknown:
            msg = f"actuator_limits.kinds: unknown {unknown}; known: {list(ACTUATOR_LIMIT_KINDS)}"
            raise ValueError(msg)
        self.kinds = kinds
        self.beta = {k: float(settings.get(f"{k}_beta", 1.0)) for k in ACTUATOR_LIMIT_KINDS}
        self.floor = float(settings.get("share_floor", 0.3))
        self.stroke_activation = float(settings.get("stroke_activation", 0.8))
        ones = np.ones(NUM_JOINTS)
        self.factors = {k: np.asarray((factors or {}).get(k, ones), dtype=float) for k in ACTUATOR_LIMIT_KINDS}
        self.knots = knots
        self.tightening = {k: np.ones((knots, NUM_JOINTS)) for k in ACTUATOR_LIMIT_KINDS}
        units = []
        for model in parallel_units():
            joints = np.array([JOINT_INDEX[j] for j in model.joints], dtype=np.intp)
            interval = self._stroke_interval(model, joints) if model.dof == 1 else None
            units.append(_Unit(model, joints, interval))
        self.units = tuple(units)

    def _unit_factor(self, kind: str, joints: npt.NDArray[np.intp]) -> float:
        """One factor per unit (its actuators share a type): the largest of its joints' (as LimitScale does)."""
        return float(self.factors[kind][joints].max())

    def _stroke(self, model: SubmechanismModel, joints: npt.NDArray[np.intp]) -> tuple[FloatArray, FloatArray]:
        lo, hi = model.limits.length_min, model.limits.length_max
        half = 0.5 * (hi - lo) * self.beta["stroke"] * self._unit_factor("stroke", joints)
        mid = 0.5 * (hi + lo)
        return mid - half, mid + half

    def _stroke_interval(self, model: SubmechanismModel, joints: npt.NDArray[np.intp]) -> tuple[float, float]:
        """The joint interval of a 1-DoF unit whose actuator length lies inside the (shrunk, scaled) stroke."""
        limits = joint_limits()
        j = int(joints[0])
        y = np.linspace(limits.position_lower[j] - 0.3, limits.position_upper[j] + 0.3, _GRID)[:, None]
        length = model.inverse(y)[:, 0]
        lo, hi = self._stroke(model, joints)
        inside = y[(length >= lo[0]) & (length <= hi[0]), 0]
        if inside.size == 0:
            return (0.0, 0.0)
        return (float(inside.min()), float(inside.max()))

    def tighten(self, kind: str, knots: Sequence[int], joints: Sequence[int], factor: float) -> None:
        """Multiply the bounds of ``kind`` at ``knots`` for ``joints`` by ``factor`` (< 1 tightens) from now on."""
        rows = np.asarray(knots, dtype=np.intp)
        cols = np.asarray(joints, dtype=np.intp)
        self.tightening[kind][np.ix_(rows, cols)] *= factor

    def boxes(self, q: FloatArray, v: FloatArray, tau: FloatArray | None) -> JointBoxes:
        """Boxes at the iterate: joint positions and velocities (N, 32) and torques (N, 32) or None (JOINT_NAMES
        order; rows of ``tau`` beyond its length, the terminal node, get no torque bound)."""
        n = q.shape[0]
        inf = np.full((n, NUM_JOINTS), np.inf)
        q_lo, q_hi, v_max, tau_max = -inf.copy(), inf.copy(), inf.copy(), inf.copy()
        tight = {k: t[:n] for k, t in self.tightening.items()}
        for unit in self.units:
            model, jj = unit.model, unit.joints
            y = q[:, jj]
            jac = model.jacobian(y)  # (N, m, m)
            if "stroke" in self.kinds:
                lo, hi = self._stroke_boxes(unit, y, jac)
                bounded = np.isfinite(lo) & np.isfinite(hi)
                mid = np.where(bounded, 0.5 * (np.where(bounded, lo, 0.0) + np.where(bounded, hi, 0.0)), 0.0)
                half = 0.5 * (hi - lo) * tight["stroke"][:, jj]
                q_lo[:, jj] = np.where(bounded, mid - half, lo)
                q_hi[:, jj] = np.where(bounded, mid + half, hi)
            if "velocity" in self.kinds:
                limit = float(model.limits.velocity_max[0]) * self.beta["velocity"] * self._unit_factor("velocity", jj)
                box = _share_box(jac, limit, np.abs(v[:, jj]), self.floor)
                v_max[:, jj] = box * tight["velocity"][:, jj]
            if "force" in self.kinds and tau is not None:
                k = tau.shape[0]
                inv_t = np.linalg.inv(np.swapaxes(jac[:k], -1, -2))  # f = J^-T tau
                limit = float(model.limits.force_max[0]) * self.beta["force"] * self._unit_factor("force", jj)
                box = _share_box(inv_t, limit, np.abs(tau[:, jj]), self.floor)
                tau_max[:k, jj] = box * tight["force"][:k, jj]
        return JointBoxes(q_lo, q_hi, v_max, tau_max)

    def _stroke_boxes(self, unit: _Unit, y: FloatArray, jac: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Joint position boxes (N, m) of one unit: the fixed interval (1-DoF) or the stroke slack linearised about
        ``y`` and shared between the joints (2-DoF)."""
        if unit.stroke_interval is not None:
            lo, hi = unit.stroke_interval
            return np.full(y.shape, lo), np.full(y.shape, hi)
        model = unit.model
        length = model.inverse(y)  # (N, m)
        lmin, lmax = self._stroke(model, unit.joints)
        up, down = lmax - length, length - lmin  # slack of each actuator to either end (negative: violated)
        absj = np.abs(jac)
        total = absj.sum(axis=2, keepdims=True)  # (N, m_act, 1): weights 1
        share = np.where(total > 0, 1.0 / np.maximum(total, 1e-300), np.inf)  # slack per unit |J_ij| d_j
        positive = jac > 0
        # moving joint j up moves actuator i up where J_ij > 0 (uses its upper slack), down where J_ij < 0
        room_up = np.where(positive, up[:, :, None], down[:, :, None]) * share
        room_down = np.where(positive, down[:, :, None], up[:, :, None]) * share
        touched = absj > 0
        d_up = np.where(touched, room_up, np.inf).min(axis=1)  # (N, m)
        d_down = np.where(touched, room_down, np.inf).min(axis=1)
        lo, hi = y - d_down, y + d_up
        empty = lo > hi  # an iterate far outside: keep it at the middle of the two bounds
        middle = 0.5 * (lo + hi)
        lo, hi = np.where(empty, middle, lo), np.where(empty, middle, hi)
        # only near the stroke ends: the shared slack would otherwise restrict joints far from any stroke limit
        usage = np.abs(length - 0.5 * (lmax + lmin)) / (0.5 * (lmax - lmin))
        near = (usage.max(axis=1) >= self.stroke_activation)[:, None]
        return np.where(near, lo, -np.inf), np.where(near, hi, np.inf)
