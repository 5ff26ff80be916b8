"""The warm start of a solve: a kinematic state guess along the knots' targets.

The quasi-static torques of ``problem.quasiStatic`` are taken on a state guess. In-place motions (squats, balancing)
use the initial state at every knot. Motions that move the base (walks, jumps) use a kinematic guess
(:func:`state_guess`): node i gets whole-body IK to knot i's sole targets and a CoM path (the knot's CoM target,
else a linear inverted pendulum whose ZMP walks from stance sole to stance sole), velocities by backward
differences as the symplectic Euler step makes them. That is our reading of the paper's remark that walking above
0.35 m/s needs a predefined CoM trajectory as initialisation; fast_walk_1m_s also tracks its CoM path as a cost (its
table row has the CoM term).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from rh5_msgs_py.array_types import FloatArray

from ..motions import SIDES, KnotSpec, MotionSpec
from .ik import solve_ik
from .robot import RobotSetup

__all__ = ["state_guess"]


def _zmp_reference(specs: Sequence[KnotSpec]) -> tuple[FloatArray, FloatArray]:
    """Per running (non-impulse) knot, the xy point the CoP should be at and how firmly: the stance sole in
    single support (weight 1); a smoothstep from one stance sole to the next over each double-support block
    (from/to the middle of the feet at the start/end of the motion) with weight 0.1, since the CoP may be
    anywhere between the feet there. Knots without contact keep the previous value with weight 0."""
    running = [s for s in specs if not s.impulse]
    out = np.zeros((len(running), 2))

    def stance(spec: KnotSpec) -> FloatArray | None:
        inside = [side for side in SIDES if spec.in_contact(side)]
        if len(inside) == 1:
            return np.asarray(spec.feet[inside[0]])[:2]
        if len(inside) == 2:
            return None
        return np.full(2, np.nan)

    values = [stance(s) for s in running]
    j = 0
    while j < len(running):
        if values[j] is not None:
            out[j] = values[j]
            j += 1
            continue
        end = j
        while end < len(running) and values[end] is None:
            end += 1
        mid_start = 0.5 * (np.asarray(running[j].feet["left"]) + np.asarray(running[j].feet["right"]))[:2]
        mid_end = 0.5 * (np.asarray(running[end - 1].feet["left"]) + np.asarray(running[end - 1].feet["right"]))[:2]
        before = out[j - 1] if j > 0 else mid_start
        after = values[end] if end < len(running) else mid_end
        after = before if after is None or np.isnan(after).any() else after
        for m in range(j, end):
            s = (m - j + 1) / (end - j + 1)
            smooth = s * s * (3.0 - 2.0 * s)
            out[m] = (1.0 - smooth) * before + smooth * after
        j = end
    weights = np.array([1.0 if v is not None and not np.isnan(v).any() else 0.1 for v in values])
    for m in range(len(out)):
        if np.isnan(out[m]).any():
            out[m] = out[m - 1] if m > 0 else 0.0
            weights[m] = 0.0
    return out, weights


def _lipm_com_path(zmp: FloatArray, weights: FloatArray, com0: FloatArray, dt: float) -> FloatArray:
    """CoM xy at the running knots and the final node (len(zmp) + 1 rows) of a linear inverted pendulum of
    height ``com0[2]`` whose ZMP tracks ``zmp``: weighted least squares on
    c_k - h/g (c_{k+1} - 2 c_k + c_{k-1}) / dt^2 = zmp_k, with the CoM at rest at ``com0`` at the start and at
    rest over the last ZMP at the end (firm)."""
    n = len(zmp) + 1
    ratio = float(com0[2]) / 9.81 / dt**2
    rows, rhs = [], []

    def row(entries: Mapping[int, float], value: FloatArray, weight: float) -> None:
        r = np.zeros(n)
        for idx, coeff in entries.items():
            r[idx] += coeff
        rows.append(weight * r)
        rhs.append(weight * value)

    big = 1e3
    row({0: 1.0}, com0[:2], big)
    row({1: 1.0, 0: -1.0}, np.zeros(2), big)
    for k in range(1, n - 1):
        row({k: 1.0 + 2.0 * ratio, k + 1: -ratio, k - 1: -ratio}, zmp[k], float(weights[k]))
    row({n - 1: 1.0, n - 2: -1.0}, np.zeros(2), big)
    row({n - 1: 1.0}, zmp[-1], big)
    solution, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    return np.asarray(solution)


def state_guess(
    motion: MotionSpec, robot: RobotSetup, specs: Sequence[KnotSpec], rotations: Mapping[str, FloatArray]
) -> list[FloatArray]:
    """Kinematic warm start: per node, IK to the sole targets of its knot and a CoM path, velocities by
    backward differences (zero after an impulse node). Node i carries knot i's targets (its running cost is evaluated
    on x_i); the final node those of the last knot. The CoM path is the knot's CoM target where the motion
    has one, else a linear inverted pendulum whose ZMP walks from sole to sole (:func:`_lipm_com_path`), at
    the initial CoM height."""
    model = robot.model
    nq = model.nq
    reference = robot.reference()
    n = len(specs)
    com_xy = _lipm_com_path(*_zmp_reference(specs), reference.com, motion.dt)
    running = -1
    qs = []
    q = robot.x0[:nq].copy()
    for i in range(n + 1):
        spec = specs[min(i, n - 1)]
        if i == n or not spec.impulse:
            running += 1
        if spec.com_guess is not None:
            com = np.asarray(spec.com_guess)
        elif spec.com is not None:
            com = np.asarray(spec.com)
        else:
            com = np.array([*com_xy[max(running, 0)], reference.com[2]])
        soles = {side: pin.SE3(rotations[side], np.asarray(spec.feet[side])) for side in SIDES}
        q = robot.x0[:nq].copy() if i == 0 else solve_ik(model, q, soles, com=com, q_ref=robot.x0[:nq], iterations=8)
        qs.append(q)
    # Backward differences, as the symplectic Euler step makes them (q_{i+1} = q_i + v_{i+1} dt): a sole that
    # leaves the ground at node i has zero velocity there. An impulse node takes no time: the node after it has
    # its configuration (the post-impact velocity is set by build_problem from the impulse model).
    xs = [robot.x0.copy()]
    for i in range(1, n + 1):
        if specs[i - 1].impulse:
            qs[i] = qs[i - 1]
            xs.append(np.concatenate([qs[i], xs[-1][nq:]]))
            continue
        v = pin.difference(model, qs[i - 1], qs[i]) / motion.dt
        xs.append(np.concatenate([qs[i], v]))
    return xs
