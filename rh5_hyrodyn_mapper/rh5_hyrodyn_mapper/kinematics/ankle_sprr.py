"""2-SPRR+1U: the RH5 ankle (roll about base x, then pitch about the rotated y), design/mechanisms.md section 5.

Leg i (HyRoDyn ``sPrr2u1``): the actuator runs from the shank pivot s_i (a U joint in the URDF) to the rod end k_i,
which sits on a crank turning about the foot-fixed axis (centre f_i, unit direction a_i) at radius r_i. The rod-end
revolute is perpendicular to the plane of the crank axis and the crank, so the rod line meets the crank axis and k_i
is the point of the crank circle closest to s_i (5.1). With f = R f_0, a = R a_0, delta = s - f:

    alpha = a . delta,  rho = |delta - alpha a|,  l = sqrt(alpha^2 + (rho - r)^2)               (5.2, closed form)
    k = f + r (delta - alpha a) / rho,  l_dot = (s x k) . omega / l                              (5.3, envelope theorem)
    l_ddot from the scalar identities D = |delta|^2, A = a . delta, rho^2 = D - A^2, l^2 = D + r^2 - 2 r rho   (5.4)

The crank turns relative to the foot, so freezing it (as the envelope theorem allows for J) is wrong at second
order; the bias differentiates the scalar identities twice instead. Forward kinematics is Newton
(UniversalJointPlatform), as in HyRoDyn; a closed form is impractical (up to 32 roots, 5.5).

The crank centre f_i is the projection of the URDF rod end k_i onto the crank axis line, so the URDF zero pose is
reproduced to the closest-point construction's accuracy (k_i in LLAnkle.urdf lies 2.5-7.8 um from the closest
point, which moves l0 by less than 2 nm).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .base import ActuatorLimits, FloatArray, as_samples, frozen_array
from .spu import Scalar, Trig, UniversalJointPlatform, _trig_array

__all__ = ["Ankle2SPRR1U"]


class Ankle2SPRR1U(UniversalJointPlatform):
    """2-SPRR+1U unit (RH5 ankles).

    Args:
        name, joints, actuators: as in rh5_msgs_py.names.SUBMECHANISMS (joints: roll, pitch).
        joint_axes: (2, 3) unit axes in the base frame at y = 0 (roll: fixed in the shank; pitch: carried by roll).
        shank_pivots: (2, 3) actuator pivots s_i on the shank, base frame [m].
        crank_centres: (2, 3) centres f_i of the crank circles (on the crank axes) at y = 0, base frame [m].
        crank_axes: (2, 3) crank axis directions a_i at y = 0, base frame.
        crank_radii: (2,) crank radii r_i [m].
        limits: ActuatorLimits of the two actuators (stroke as absolute pivot-to-pivot length l).
    """

    def __init__(
        self,
        name: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        joint_axes: npt.ArrayLike,
        shank_pivots: npt.ArrayLike,
        crank_centres: npt.ArrayLike,
        crank_axes: npt.ArrayLike,
        crank_radii: npt.ArrayLike,
        limits: ActuatorLimits,
        **newton: Any,
    ) -> None:
        super().__init__(name, "2-SPRR+1U", joints, actuators, limits=limits, joint_axes=joint_axes, **newton)
        shank = np.asarray(shank_pivots, dtype=np.float64)
        centres = np.asarray(crank_centres, dtype=np.float64)
        axes = np.asarray(crank_axes, dtype=np.float64)
        radii = np.asarray(crank_radii, dtype=np.float64)
        if shank.shape != (2, 3) or centres.shape != (2, 3) or axes.shape != (2, 3) or radii.shape != (2,):
            raise ValueError(f"{name}: expected (2, 3) pivots, centres, axes and (2,) radii")
        axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        self.shank_pivots = frozen_array(shank)
        self.crank_centres = frozen_array(centres)
        self.crank_axes = frozen_array(axes)
        self.crank_radii = frozen_array(radii)
        self._legs = tuple(
            (*self._canonical(s), *self._canonical(f), *self._canonical(a), float(r))
            for s, f, a, r in zip(shank, centres, axes, radii, strict=True)
        )
        self._finish()

    @classmethod
    def from_points(
        cls,
        name: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        joint_axes: npt.ArrayLike,
        shank_pivots: npt.ArrayLike,
        crank_pivots: npt.ArrayLike,
        crank_axes: npt.ArrayLike,
        rod_ends: npt.ArrayLike,
        limits: ActuatorLimits,
        **newton: Any,
    ) -> Ankle2SPRR1U:
        """Build from URDF points: any point on each crank axis and the rod ends k_i at y = 0 (geometry.yaml).

        The crank circle's centre is the projection of k_i onto the crank axis line, its radius the distance of k_i
        from that line: exactly the circle k_i runs on when the crank turns.
        """
        pivots = np.asarray(crank_pivots, dtype=np.float64)
        axes = np.asarray(crank_axes, dtype=np.float64)
        axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
        k = np.asarray(rod_ends, dtype=np.float64)
        centres = pivots + np.sum((k - pivots) * axes, axis=-1, keepdims=True) * axes
        radii = np.linalg.norm(k - centres, axis=-1)
        return cls(
            name,
            joints,
            actuators,
            joint_axes=joint_axes,
            shank_pivots=shank_pivots,
            crank_centres=centres,
            crank_axes=axes,
            crank_radii=radii,
            limits=limits,
            **newton,
        )

    def rod_ends(self, y: FloatArray) -> FloatArray:
        """Rod-end points k_i(y) in the base frame; (..., 2) -> (..., 2, 3) (for plots and tests)."""
        trig = _trig_array(as_samples(self.name, y, 2))
        out = []
        for leg in self._legs:
            k = _leg(leg, trig)[4]
            out.append(np.stack(k, axis=-1))
        return np.stack(out, axis=-2) @ self.canonical_frame.T

    def _lengths(self, trig: Trig) -> tuple[Scalar, Scalar]:
        return _leg(self._legs[0], trig)[0], _leg(self._legs[1], trig)[0]

    def _fused(self, trig: Trig, rates: tuple[Scalar, Scalar] | None) -> tuple[Scalar, ...]:
        """Lengths, Jacobian and bias in one pass over the legs (the pose part is ``_leg``, inlined for speed)."""
        c0, s0, c1, s1 = trig
        if rates is not None:
            w0, w1 = rates
            ox, oy, oz = w0, c0 * w1, s0 * w1  # omega = W y_dot
            by, bz = -s0 * w0 * w1, c0 * w0 * w1  # alpha; alpha_x = 0
        out: list[Scalar] = []
        for sx, sy, sz, fx0, fy0, fz0, ax0, ay0, az0, r in self._legs:
            fx = c1 * fx0 + s1 * fz0  # _leg: f = Rx(y0) Ry(y1) f0
            t = c1 * fz0 - s1 * fx0
            fy = c0 * fy0 - s0 * t
            fz = s0 * fy0 + c0 * t
            ax = c1 * ax0 + s1 * az0  # a = Rx(y0) Ry(y1) a0
            t = c1 * az0 - s1 * ax0
            ay = c0 * ay0 - s0 * t
            az = s0 * ay0 + c0 * t
            tx, ty, tz = sx - fx, sy - fy, sz - fz  # delta = s - f
            alpha = ax * tx + ay * ty + az * tz
            px, py, pz = tx - alpha * ax, ty - alpha * ay, tz - alpha * az
            rho = (px * px + py * py + pz * pz) ** 0.5
            e = rho - r
            l = (alpha * alpha + e * e) ** 0.5
            g = r / rho
            kx, ky, kz = fx + g * px, fy + g * py, fz + g * pz
            my, mz = sz * kx - sx * kz, sx * ky - sy * kx  # s x k; n x k = (s x k) / l
            out += (l, (sy * kz - sz * ky) / l, (c0 * my + s0 * mz) / l)  # W = [(1,0,0), (0,c0,s0)]
            if rates is None:
                out.append(None)
                continue
            vx, vy, vz = oy * fz - oz * fy, oz * fx - ox * fz, ox * fy - oy * fx  # f_dot = omega x f
            qx, qy, qz = oy * vz - oz * vy, oz * vx - ox * vz, ox * vy - oy * vx
            fddx, fddy, fddz = by * fz - bz * fy + qx, bz * fx + qy, -by * fx + qz  # f_ddot = alpha x f + omega x f_dot
            gx, gy, gz = oy * az - oz * ay, oz * ax - ox * az, ox * ay - oy * ax  # a_dot = omega x a
            hx, hy, hz = oy * gz - oz * gy, oz * gx - ox * gz, ox * gy - oy * gx
            addx, addy, addz = by * az - bz * ay + hx, bz * ax + hy, -by * ax + hz  # a_ddot
            d_dot = -(tx * vx + ty * vy + tz * vz)  # D_dot / 2 (delta_dot = -f_dot)
            d_ddot = vx * vx + vy * vy + vz * vz - (tx * fddx + ty * fddy + tz * fddz)  # D_ddot / 2
            a_dot = gx * tx + gy * ty + gz * tz - (ax * vx + ay * vy + az * vz)  # A = a . delta = alpha
            a_ddot = (
                addx * tx
                + addy * ty
                + addz * tz
                - 2.0 * (gx * vx + gy * vy + gz * vz)
                - (ax * fddx + ay * fddy + az * fddz)
            )
            rho_dot = (d_dot - alpha * a_dot) / rho
            rho_ddot = (d_ddot - a_dot * a_dot - alpha * a_ddot - rho_dot * rho_dot) / rho
            l_dot = (d_dot - r * rho_dot) / l
            out.append((d_ddot - r * rho_ddot - l_dot * l_dot) / l)
        return out[0], out[4], out[1], out[2], out[5], out[6], out[3], out[7]


def _leg(leg: tuple[float, ...], trig: Trig) -> tuple[Any, ...]:
    """(l, f, a, rho, k) of one leg at the pose ``trig`` = (cos y0, sin y0, cos y1, sin y1), canonical frame."""
    c0, s0, c1, s1 = trig
    sx, sy, sz, fx0, fy0, fz0, ax0, ay0, az0, r = leg
    fx = c1 * fx0 + s1 * fz0  # f = Rx(y0) Ry(y1) f0
    t = c1 * fz0 - s1 * fx0
    fy = c0 * fy0 - s0 * t
    fz = s0 * fy0 + c0 * t
    ax = c1 * ax0 + s1 * az0  # a = Rx(y0) Ry(y1) a0
    t = c1 * az0 - s1 * ax0
    ay = c0 * ay0 - s0 * t
    az = s0 * ay0 + c0 * t
    dx, dy, dz = sx - fx, sy - fy, sz - fz
    alpha = ax * dx + ay * dy + az * dz
    px, py, pz = dx - alpha * ax, dy - alpha * ay, dz - alpha * az
    rho = (px * px + py * py + pz * pz) ** 0.5
    e = rho - r
    l = (alpha * alpha + e * e) ** 0.5
    g = r / rho
    return l, (fx, fy, fz), (ax, ay, az), rho, (fx + g * px, fy + g * py, fz + g * pz)
