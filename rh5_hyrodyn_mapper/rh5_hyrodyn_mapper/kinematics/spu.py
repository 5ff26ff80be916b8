"""2-SPU+1U: a platform on a universal joint driven by two U-P-S legs (RH5 torso pitch/roll and the wrists).

design/mechanisms.md section 4. The platform turns about the first joint axis w1 (fixed in the base), then about
the second axis w2 (carried by the first joint): R(y) = Rot(w1, y0) Rot(w2, y1). Both axes pass through the base
origin. The models work in the "canonical" frame C = [w1, w2, w1 x w2] of the base, where R(y) = Rx(y0) Ry(y1);
every point is converted once at construction, so the joint axes of the public files are used exactly (the torso's
axes are 3.7e-6 rad off the base axes because the URDF rounds pi/2 to 1.5708).

Leg i: base U-joint centre b_i, platform S-joint centre e_i0 at y = 0; l_i(y) = |R(y) e_i0 - b_i| (4.2).
Jacobian (4.3): l_dot_i = (b_i x e_i) . omega / l_i with omega = W(y) y_dot, W = [x, Rx(y0) y].
Bias (4.4): l_ddot_i = n_i . e_ddot_i + (|e_dot_i|^2 - (n_i . e_dot_i)^2) / l_i at y_ddot = 0.

``UniversalJointPlatform`` holds what the SPU and the ankle's 2-SPRR+1U share: the U joint's canonical frame, the
zero pose and working mode, and the Newton settings of the forward kinematics (HyRoDyn's approach) with its error
texts. The maths itself (legs, Newton, the closed-form 2x2 statics) runs in the C kernels (``unit_maps.c``).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray

from . import kernels
from .base import ActuatorLimits, ForwardKinematicsError, ImmutableModel, KinematicsError, frozen_array

__all__ = ["Platform2SPU1U", "UniversalJointPlatform"]


class UniversalJointPlatform(ImmutableModel):
    """Base of the 2-DOF units on a 1U joint; subclasses set ``_legs``, their legs' kernel constants, then ``_finish``.

    Forward kinematics: Newton on IK(y) = l, warm-started from ``y_guess`` or cold-started from J(0)^-1 (l - l0),
    steps clamped to ``max_step`` rad, converged when |IK(y) - l|_inf <= ``tolerance`` (m); it must end in the
    working mode of the zero pose (same sign of det J), else ForwardKinematicsError.
    """

    def __init__(
        self,
        name: str,
        kind: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        limits: ActuatorLimits,
        joint_axes: npt.ArrayLike,
        max_iterations: int = 20,
        tolerance: float = 1e-13,
        max_step: float = 0.5,
    ) -> None:
        super().__init__(name, kind, joints, actuators, limits)
        if len(self.joints) != 2 or len(self.actuators) != 2:
            raise ValueError(f"{name}: a {kind} unit has 2 joints and 2 actuators")
        axes = np.asarray(joint_axes, dtype=np.float64)
        if axes.shape != (2, 3):
            raise ValueError(f"{name}: joint_axes must be 2 unit vectors (2, 3)")
        w1 = axes[0] / np.linalg.norm(axes[0])
        w2 = axes[1] / np.linalg.norm(axes[1])
        if abs(w1 @ w2) > 1e-6:
            raise ValueError(f"{name}: the U-joint axes are not orthogonal (w1 . w2 = {w1 @ w2:.3g})")
        w2 = w2 - (w1 @ w2) * w1
        w2 /= np.linalg.norm(w2)
        self.joint_axes = frozen_array([w1, w2])
        self.canonical_frame = frozen_array(np.column_stack((w1, w2, np.cross(w1, w2))))
        self.max_iterations = int(max_iterations)
        self.tolerance = float(tolerance)
        self.max_step = float(max_step)
        self.l0 = frozen_array(np.zeros(2))  # until _finish() evaluates the zero pose
        self.jacobian0 = frozen_array(np.eye(2))
        self._mode = 1.0

    # --- construction helpers ------------------------------------------------------------------------------------

    def _canonical(self, point: npt.ArrayLike) -> tuple[float, float, float]:
        """A base-frame vector in the canonical frame (w1, w2, w1 x w2), as Python floats."""
        x, y, z = (self.canonical_frame.T @ np.asarray(point, dtype=np.float64)).tolist()
        return x, y, z

    def _finish(self) -> None:
        """Zero-pose quantities (l0, J(0), the working-mode sign) from the kernels, then freeze the model."""
        self._set_table()
        self.l0 = frozen_array(self.inverse(np.zeros(2)))
        jac0 = self.jacobian(np.zeros(2))
        det0 = float(np.linalg.det(jac0))
        if not abs(det0) > 0.0:
            raise ValueError(f"{self.name}: singular at the zero pose")
        self.jacobian0 = frozen_array(jac0)
        self._mode = math.copysign(1.0, det0)
        self._freeze()

    def with_newton(self, *, tolerance: float, max_iterations: int) -> UniversalJointPlatform:
        """The same unit with other forward-kinematics stop criteria (a new immutable model; this one is kept)."""
        clone = copy.copy(self)
        object.__setattr__(clone, "tolerance", float(tolerance))
        object.__setattr__(clone, "max_iterations", int(max_iterations))
        clone._set_table()
        return clone

    # --- the kernel row and the error texts ------------------------------------------------------------------------

    _legs: tuple[tuple[float, ...], ...]
    """Per leg, its constants in the canonical frame as the kernel row lays them out (``unit_maps.h``)."""

    def kernel_constants(self) -> tuple[int, list[float]]:
        """The kernel row: l0, J(0)^-1 (cold start), working mode, Newton settings, then the legs."""
        kind = kernels.KIND_SPU if self.kind == "2-SPU+1U" else kernels.KIND_SPRR
        newton = [self._mode, self.tolerance, float(self.max_iterations), self.max_step]
        jinv0 = np.linalg.inv(self.jacobian0).ravel().tolist()
        legs = [value for leg in self._legs for value in leg]
        return kind, [*self.l0.tolist(), *jinv0, *newton, *legs]

    def _refusal(self, conditions: FloatArray, max_condition: float) -> str:
        worst = float(np.max(conditions))
        return f"{self.name}: force map refused near a singular pose (cond(J) = {worst:.3g} > {max_condition:.3g})"

    def _forward_error(self, l: FloatArray, info: FloatArray) -> KinematicsError:
        status, residual = info[:, 0], info[:, 1]
        bad = status == kernels.FK_WRONG_MODE
        why = "converged outside the working mode of the zero pose"
        if not np.any(bad):
            bad = status == kernels.FK_NOT_CONVERGED
            why = "Newton did not converge (lengths not assemblable?)"
        finite = residual[bad & np.isfinite(residual)]
        worst = float(finite.max()) if finite.size else math.nan
        first = l[np.flatnonzero(bad)[0]]
        return ForwardKinematicsError(
            f"{self.name}: forward kinematics failed for {int(bad.sum())} of {status.size} sample(s): {why} "
            f"(max residual {worst:.3g} m after {self.max_iterations} Newton iterations at most; "
            f"first failing l = {np.array2string(first, precision=6)} m)"
        )


class Platform2SPU1U(UniversalJointPlatform):
    """2-SPU+1U unit (RH5 torso, wrists): legs U (base, b_i) - P (actuator) - S (platform, e_i0 at y = 0).

    Args:
        name, joints, actuators: as in rh5_msgs_py.names.SUBMECHANISMS.
        joint_axes: (2, 3) unit axes in the base frame at y = 0: joint 1 (fixed in the base), joint 2 (carried by 1).
        base_pivots: (2, 3) U-joint centres b_i in the base frame [m].
        platform_pivots: (2, 3) S-joint centres e_i0 in the base frame at y = 0 [m].
        limits: ActuatorLimits of the two actuators (stroke as absolute pivot-to-pivot length l).
    """

    def __init__(
        self,
        name: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        joint_axes: npt.ArrayLike,
        base_pivots: npt.ArrayLike,
        platform_pivots: npt.ArrayLike,
        limits: ActuatorLimits,
        **newton: Any,
    ) -> None:
        super().__init__(name, "2-SPU+1U", joints, actuators, limits=limits, joint_axes=joint_axes, **newton)
        base = np.asarray(base_pivots, dtype=np.float64)
        platform = np.asarray(platform_pivots, dtype=np.float64)
        if base.shape != (2, 3) or platform.shape != (2, 3):
            raise ValueError(f"{name}: base_pivots and platform_pivots must have shape (2, 3)")
        self.base_pivots = frozen_array(base)
        self.platform_pivots = frozen_array(platform)
        # per leg: the base U joint b and the platform S joint e0 at y = 0
        self._legs = tuple(self._canonical(b) + self._canonical(e) for b, e in zip(base, platform, strict=True))
        self._finish()
