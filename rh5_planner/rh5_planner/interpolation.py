"""1 kHz interpolation of a planned trajectory (the paper: "interpolated to 1 kHz using cubic splines").

Works on a :class:`rh5_msgs_py.trajectory_file.TrajectoryData` (a :class:`rh5_planner.ocp.PlanResult`
converts with ``to_trajectory_data()``):

* Joints and base position: cubic Hermite splines through the knot positions (C1), with Euler-consistent
  slopes (`euler_tangents`): Crocoddyl's semi-implicit Euler moves segment k at the velocity stored at knot
  k+1 (q_{k+1} = q_k + dt v_{k+1}), i.e. with constant acceleration (v_{k+1} - v_k) / dt from the mean
  velocity (v_k + v_{k+1}) / 2. That mean is the slope at knot k (the first and last knots keep theirs: the
  robot starts and ends in the planned state). Slopes equal to the knot velocities instead make each
  segment's acceleration swing between 4 a and -2 a (measured on the 5 kg walk: reference RMS acceleration
  13.2 rad/s^2 against the plan's own 10.6; 8.3 with these slopes). A joint whose cubic would still outrun
  every velocity planned for its segment (an impulse's velocity step) moves linearly there instead
  (`_limit_overshoot`).
  The base linear velocity of the file is expressed in the base frame (pinocchio LOCAL), so the slope of
  the world position is ``R(q) v_lin``.
* Base orientation: a cubic Hermite curve on SO(3) in the tangent space of the segment's start rotation:
  phi(0) = 0, phi(1) = log(R0^T R1), end slopes from the (Euler-consistent) body angular velocities, then
  R(t) = R0 exp(phi(t)) (Pinocchio's exp3 and log3); written back as a unit quaternion xyzw.
* Velocities: the analytic derivative of the position splines (joints), and the knot velocities linearly
  interpolated for the base twist.
* Torques and contact wrenches: zero-order hold over each knot interval, exactly as the Euler integrator
  applied the control ``u_k`` from knot k to k+1 (the contact forces are those of the same interval); a
  linear blend would feed the stabiliser torques the optimiser never applied. Contact phases and CoPs are
  held too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from rh5_hyrodyn_mapper.tf_tree import rotation_to_quaternion
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.hermite import hermite_curvature_weights, hermite_weights
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData

__all__ = ["RATE_HZ", "Interpolated", "euler_tangents", "hermite", "interpolate"]

RATE_HZ: Final = 1000.0


def hermite(
    p0: FloatArray, p1: FloatArray, m0: FloatArray, m1: FloatArray, *, h: float, s: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cubic Hermite value, first and second time derivative at normalised times ``s`` in [0, 1] over a segment of
    ``h`` s.

    ``p*`` are (d,) end values, ``m*`` end slopes per second. Returns arrays of shape (len(s), d).
    """
    weights, slopes = hermite_weights(s)
    ends = np.stack(np.broadcast_arrays(p0, h * m0, p1, h * m1))
    return weights.T @ ends, slopes.T @ ends / h, hermite_curvature_weights(s).T @ ends / h**2


def euler_tangents(velocities: FloatArray) -> FloatArray:
    """Spline slopes at the knots of a semi-implicit Euler plan: (v_k + v_{k+1}) / 2, the first and last kept.

    ``velocities`` is (N, d) (the knot velocities, one row per knot)."""
    v = np.asarray(velocities, dtype=np.float64)
    slopes = v.copy()
    if v.shape[0] > 2:
        slopes[1:-1] = 0.5 * (v[1:-1] + v[2:])
    return slopes


@dataclass(frozen=True, eq=False)
class Interpolated:
    """Samples at ``rate_hz``: times (M,), states (M, NX) in the file layout, controls (M, 32) (zero-order hold),
    contact wrenches (M, 2, 6), contact phases (M, 2) and CoPs (M, 2, 2) (held)."""

    times: FloatArray
    states: FloatArray
    controls: FloatArray
    contact_wrenches: FloatArray
    contact_phases: npt.NDArray[np.bool_]
    cop: FloatArray
    joint_accelerations: FloatArray


KNOT_SNAP_S = 1e-9


def _limit_overshoot(  # noqa: PLR0917 - the segment's arrays, in place
    p: FloatArray,
    dp: FloatArray,
    d2: FloatArray,
    q0: FloatArray,
    q1: FloatArray,
    v0: FloatArray,
    v1: FloatArray,
    h: float,
    s: FloatArray,
) -> None:
    """Where a joint's cubic is faster than anything planned for its segment, interpolate it linearly instead.

    ``v0``, ``v1`` bound the planned speeds at the segment's ends (knot velocities and spline slopes). The
    velocity may jump at a knot (a touch-down impulse, a fast phase change), and a cubic through such knots can
    outrun every planned speed (measured on the 5 kg walk with the knot velocities as slopes: LRKnee 3.1 rad/s
    between knots within 2.4 rad/s, its limit). On such segments the joint moves linearly at the planned
    segment velocity, as the optimiser's integrator did; the knots are still hit exactly."""
    secant = (q1 - q0) / h
    envelope = np.maximum(np.maximum(np.abs(v0), np.abs(v1)), np.abs(secant)) * (1.0 + 1e-9) + 1e-12
    over = (np.abs(dp) > envelope).any(axis=0)
    if not over.any():
        return
    p[:, over] = q0[over] + s[:, None] * (q1 - q0)[over]
    dp[:, over] = secant[over]
    d2[:, over] = 0.0


def interpolate(data: TrajectoryData, rate_hz: float = RATE_HZ, *, joints_only: bool = False) -> Interpolated:
    """Sample ``data`` at ``rate_hz`` from its first to its last knot time (the knot times are always hit).

    ``joints_only`` leaves the base (position, orientation, twist) at zero: the joints come out the same, ~10x
    faster (the planner's check of the actuator limits at 1 kHz needs the joints alone)."""
    times = data.times
    x = data.states
    n = times.size
    step = 1.0 / rate_hz
    count = int(np.floor((times[-1] - times[0]) / step + 1e-9)) + 1
    grid = times[0] + step * np.arange(count)
    if n > 1:  # every knot exactly once: grid points within a nanosecond of a knot give way to it
        pos = np.clip(np.searchsorted(times, grid), 1, n - 1)
        nearest = np.minimum(np.abs(grid - times[pos - 1]), np.abs(grid - times[pos]))
        grid = grid[nearest > KNOT_SNAP_S]
    grid = np.union1d(grid, times)
    seg = np.clip(np.searchsorted(times, grid, side="right") - 1, 0, max(0, n - 2))
    out = np.zeros((grid.size, x.shape[1]))
    acc = np.zeros((grid.size, x.shape[1] - NQ - 6))
    nj = x.shape[1] - NQ - 6
    rotations = np.array([pin.Quaternion(w, qx, qy, qz).normalized().toRotationMatrix() for qx, qy, qz, w in x[:, 3:7]])
    joint_slopes = euler_tangents(x[:, NQ + 6 :])
    base_slopes = euler_tangents(np.einsum("kij,kj->ki", rotations, x[:, NQ : NQ + 3]))  # world frame
    spin_slopes = euler_tangents(x[:, NQ + 3 : NQ + 6])  # body frame
    for k in range(max(1, n - 1)):
        mask = seg == k
        if n == 1:
            out[:] = x[0]
            break
        h = times[k + 1] - times[k]
        s = (grid[mask] - times[k]) / h
        x0, x1 = x[k], x[k + 1]
        m0, m1 = joint_slopes[k], joint_slopes[k + 1]
        # joints
        p, dp, d2 = hermite(x0[7:NQ], x1[7:NQ], m0, m1, h=h, s=s)
        s_col = s[:, None]
        speed0 = np.maximum(np.abs(x0[NQ + 6 :]), np.abs(m0))
        speed1 = np.maximum(np.abs(x1[NQ + 6 :]), np.abs(m1))
        _limit_overshoot(p, dp, d2, x0[7:NQ], x1[7:NQ], speed0, speed1, h, s)
        out[mask, 7:NQ] = p
        out[mask, NQ + 6 :] = dp
        acc[mask] = d2[:, :nj]
        if joints_only:
            continue
        # base position (world)
        r0, r1 = rotations[k], rotations[k + 1]
        p, _, _ = hermite(x0[:3], x1[:3], base_slopes[k], base_slopes[k + 1], h=h, s=s)
        out[mask, :3] = p
        # base orientation: Hermite in the tangent space at r0
        phi1 = pin.log3(r0.T @ r1)
        phi, _, _ = hermite(np.zeros(3), phi1, spin_slopes[k], spin_slopes[k + 1], h=h, s=s)
        out[mask, 3:7] = np.array([rotation_to_quaternion(r0 @ pin.exp3(f)) for f in phi])
        # base twist: linear blend of the knot twists
        out[mask, NQ : NQ + 6] = (1 - s_col) * x0[NQ : NQ + 6] + s_col * x1[NQ : NQ + 6]
    controls = data.controls
    held = np.minimum(seg, controls.shape[0] - 1)
    knot_hold = np.clip(np.searchsorted(times, grid + 1e-12, side="right") - 1, 0, n - 1)
    return Interpolated(
        times=grid,
        states=out,
        controls=controls[held],
        contact_wrenches=data.contact_wrenches[knot_hold],
        contact_phases=data.contact_phases[knot_hold],
        cop=data.cop[knot_hold],
        joint_accelerations=acc,
    )
