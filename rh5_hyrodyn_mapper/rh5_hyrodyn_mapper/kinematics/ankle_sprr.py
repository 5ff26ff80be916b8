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
(UniversalJointPlatform), as in HyRoDyn; a closed form is impractical (up to 32 roots, 5.5). The maths runs in the
C kernels (``unit_maps.c``, kind SPRR); this model computes the legs' constants.

The crank centre f_i is the projection of the URDF rod end k_i onto the crank axis line, so the URDF zero pose is
reproduced to the closest-point construction's accuracy (k_i in LLAnkle.urdf lies 2.5-7.8 um from the closest
point, which moves l0 by less than 2 nm).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .base import ActuatorLimits, frozen_array
from .spu import UniversalJointPlatform

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
        self._legs = tuple(  # per leg: the shank pivot s, crank centre f0 and axis a0 at y = 0, the crank radius r
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
