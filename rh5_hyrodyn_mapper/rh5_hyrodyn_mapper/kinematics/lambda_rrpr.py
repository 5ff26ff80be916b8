"""1-RRPR "lambda" mechanism (RH5 Hip3 and knee), design/mechanisms.md section 3, exact in 3-D.

The driven joint turns the distal link about the axis (point O, unit direction a). The actuator runs from the stator
pivot P (proximal link) to the rod end Q (distal link, Q0 at q = 0): l(q) = |P - O - Rot(a, q) (Q0 - O)|.
Splitting p = P - O and w = Q0 - O into parts along a and normal to a (radii r1 = |p_perp|, r2 = |w_perp|, axial
offset dz = (p - w) . a) gives the exact closed form

    l(q)^2 = k0 - k1 cos(phi0 + q),   k0 = dz^2 + r1^2 + r2^2,  k1 = 2 r1 r2,

with phi0 the signed angle from p_perp to w_perp about a. This is section 3's planar formula with theta = |phi|
and s = sign(phi0) (+1 when +q opens the angle POQ), extended by the axial offset of the pivots (6 um on the RH5
knee; the planar model with the pivot distances l1, l2 instead of r1, r2 errs by 19 um there, 3.8). Then

    J = dl/dq = r1 r2 sin(phi) / l,   bias = (k1 cos(phi) / 2 - J^2) / l * q_dot^2,
    FK: cos(phi) = (k0 - l^2) / k1,  phi = s arccos(.),  q = phi - phi0   (one branch: phi keeps the sign of phi0).

The singularity guard of ``forces`` uses the scale-free condition h_max / |J|, where h_max is the largest moment
arm the geometry can reach (for a planar lambda the shorter link); it grows without bound as the actuator line
approaches O (theta -> 0 or pi).

The maths runs in the C kernels (``unit_maps.c``, kind RRPR); this model computes the constants from the geometry
and words the refusals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray

from . import kernels
from .base import ActuatorLimits, ForwardKinematicsError, ImmutableModel, KinematicsError, frozen_array

__all__ = ["Lambda1RRPR"]


class Lambda1RRPR(ImmutableModel):
    """1-RRPR lambda unit: one joint, one linear actuator, closed-form IK and FK.

    Args:
        name, joints, actuators: as in rh5_msgs_py.names.SUBMECHANISMS (one joint, one actuator).
        axis_point: a point O on the driven joint axis, base frame [m].
        axis: the driven joint axis direction a in the base frame (+q turns the distal link about +a).
        stator_pivot: P, the actuator pivot on the proximal link [m].
        rod_end: Q0, the actuator pivot on the distal link at q = 0 [m].
        limits: ActuatorLimits of the actuator (stroke as absolute pivot-to-pivot length l).
    """

    def __init__(
        self,
        name: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        axis_point: npt.ArrayLike,
        axis: npt.ArrayLike,
        stator_pivot: npt.ArrayLike,
        rod_end: npt.ArrayLike,
        limits: ActuatorLimits,
    ) -> None:
        super().__init__(name, "1-RRPR", joints, actuators, limits)
        if len(self.joints) != 1 or len(self.actuators) != 1:
            raise ValueError(f"{name}: a 1-RRPR unit has one joint and one actuator")
        o = np.asarray(axis_point, dtype=np.float64)
        a = np.asarray(axis, dtype=np.float64)
        a = a / np.linalg.norm(a)
        p = np.asarray(stator_pivot, dtype=np.float64) - o
        w = np.asarray(rod_end, dtype=np.float64) - o
        p_perp = p - (p @ a) * a
        w_perp = w - (w @ a) * a
        r1, r2 = float(np.linalg.norm(p_perp)), float(np.linalg.norm(w_perp))
        dz = float((p - w) @ a)
        phi0 = math.atan2(float(a @ np.cross(p_perp, w_perp)), float(p_perp @ w_perp))
        if not (1e-6 < abs(phi0) < math.pi - 1e-6) or min(r1, r2) <= 0.0:
            raise ValueError(f"{name}: degenerate lambda geometry (phi0 = {phi0:.3g} rad)")
        self.axis_point = frozen_array(o)
        self.axis = frozen_array(a)
        self.stator_pivot = frozen_array(o + p)
        self.rod_end = frozen_array(o + w)
        self.radii = (r1, r2)
        self.axial_offset = dz
        self.phi0 = phi0
        self.sign = math.copysign(1.0, phi0)
        self._k0 = dz * dz + r1 * r1 + r2 * r2
        self._k1 = 2.0 * r1 * r2
        self._r12 = r1 * r2
        # Largest moment arm over all q: maximise (1 - x^2) / (k0 - k1 x) over x = cos(phi).
        x = (self._k0 - math.sqrt(self._k0 * self._k0 - self._k1 * self._k1)) / self._k1
        self.moment_arm_max = self._r12 * math.sqrt(1.0 - x * x) / math.sqrt(self._k0 - self._k1 * x)
        self._set_table()
        self.l0 = frozen_array(self.inverse(np.zeros(1)))
        self._freeze()

    @property
    def theta0(self) -> float:
        """The angle POQ at q = 0 (section 3.1), in [0, pi]."""
        return abs(self.phi0)

    def kernel_constants(self) -> tuple[int, list[float]]:
        """The kernel row: phi0, k0, k1, r1 r2, the branch sign and the largest moment arm."""
        return kernels.KIND_RRPR, [self.phi0, self._k0, self._k1, self._r12, self.sign, self.moment_arm_max]

    def _refusal(self, conditions: FloatArray, max_condition: float) -> str:
        worst = float(np.max(conditions))
        return (
            f"{self.name}: force map refused near a singular pose (moment arm {self.moment_arm_max / worst:.3g} m, "
            f"condition h_max/|J| = {worst:.3g} > {max_condition:.3g})"
        )

    def _forward_error(self, l: FloatArray, info: FloatArray) -> KinematicsError:
        bad = info[:, 0] < 0
        first = int(np.flatnonzero(bad)[0])
        reach = (math.sqrt(self._k0 - self._k1), math.sqrt(self._k0 + self._k1))
        return ForwardKinematicsError(
            f"{self.name}: forward kinematics failed for {int(bad.sum())} of {bad.size} sample(s): "
            f"length {float(l[first, 0]):.6g} m is outside the assemblable range [{reach[0]:.6g}, {reach[1]:.6g}] m "
            f"(residual {float(info[first, 1]):.3g} m, closed form: 0 iterations)"
        )
