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

The fused maps ``to_actuator_space`` / ``to_joint_space`` evaluate cos and sin of phi once and derive l, J, the bias,
the force and (after the closed-form FK) y_dot and tau from them; on one sample they work on Python floats.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .base import (
    ActuatorLimits,
    FloatArray,
    ForwardKinematicsError,
    ImmutableModel,
    SingularityError,
    as_samples,
    frozen_array,
    singular_solve,
)

__all__ = ["Lambda1RRPR"]

_ROUNDING = 1e-12  # |cos(phi)| may exceed 1 by this much through rounding before a length counts as unreachable


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
        self.name = name
        self.kind = "1-RRPR"
        self.joints = tuple(joints)
        self.actuators = tuple(actuators)
        if len(self.joints) != 1 or len(self.actuators) != 1:
            raise ValueError(f"{name}: a 1-RRPR unit has one joint and one actuator")
        self.limits = limits
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
        self.l0 = frozen_array([math.sqrt(self._k0 - self._k1 * math.cos(phi0))])
        self._freeze()

    @property
    def theta0(self) -> float:
        """The angle POQ at q = 0 (section 3.1), in [0, pi]."""
        return abs(self.phi0)

    def inverse(self, y: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        if y.shape == (1,):
            return np.array((math.sqrt(self._k0 - self._k1 * math.cos(self.phi0 + float(y[0]))),))
        y = as_samples(self.name, y, 1)
        return np.sqrt(self._k0 - self._k1 * np.cos(self.phi0 + y))

    def jacobian(self, y: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        if y.shape == (1,):
            phi = self.phi0 + float(y[0])
            return np.array(((self._r12 * math.sin(phi) / math.sqrt(self._k0 - self._k1 * math.cos(phi)),),))
        phi = self.phi0 + as_samples(self.name, y, 1)
        return (self._r12 * np.sin(phi) / np.sqrt(self._k0 - self._k1 * np.cos(phi)))[..., None]

    def bias(self, y: FloatArray, yd: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        yd = np.asarray(yd, dtype=np.float64)
        if y.shape == (1,) and yd.shape == (1,):
            phi = self.phi0 + float(y[0])
            c, s = math.cos(phi), math.sin(phi)
            l = math.sqrt(self._k0 - self._k1 * c)
            j = self._r12 * s / l
            return np.array(((0.5 * self._k1 * c - j * j) / l * float(yd[0]) ** 2,))
        phi = self.phi0 + as_samples(self.name, y, 1)
        yd = as_samples(self.name, yd, 1)
        c = np.cos(phi)
        l = np.sqrt(self._k0 - self._k1 * c)
        j = self._r12 * np.sin(phi) / l
        return (0.5 * self._k1 * c - j * j) / l * yd * yd

    def forward(self, l: FloatArray, y_guess: FloatArray | None = None) -> FloatArray:
        """Closed form; ``y_guess`` is not needed (one branch)."""
        return self.forward_with_info(l, y_guess)[0]

    def forward_with_info(self, l: FloatArray, y_guess: FloatArray | None = None) -> tuple[FloatArray, Any]:
        """Joints y(l) and the iteration count (always 0: closed form), shaped like the other models' answers."""
        del y_guess
        l = np.asarray(l, dtype=np.float64)
        if l.shape == (1,):
            length = float(l[0])
            c = (self._k0 - length * length) / self._k1
            if abs(c) <= 1.0:
                return np.array((self.sign * math.acos(c) - self.phi0,)), 0
        l = as_samples(self.name, l, 1)
        c = (self._k0 - l * l) / self._k1
        bad = ~(np.abs(c) <= 1.0 + _ROUNDING)
        if np.any(bad):
            first = float(l[bad][0])
            reach = (math.sqrt(self._k0 - self._k1), math.sqrt(self._k0 + self._k1))
            raise ForwardKinematicsError(
                f"{self.name}: forward kinematics failed for {int(bad.sum())} of {bad.size} sample(s): "
                f"length {first:.6g} m is outside the assemblable range [{reach[0]:.6g}, {reach[1]:.6g}] m "
                f"(residual {_distance(first, reach):.3g} m, closed form: 0 iterations)"
            )
        y = self.sign * np.arccos(np.clip(c, -1.0, 1.0)) - self.phi0
        return y, (0 if l.shape == (1,) else np.zeros(l.shape[:-1], dtype=np.int64))

    def forces(
        self, y: FloatArray, tau: FloatArray, max_condition: float = 1e6, jac: FloatArray | None = None
    ) -> FloatArray:
        """f = tau / J; refuses (SingularityError) where h_max / |J| > ``max_condition``.

        ``jac`` may pass J(y) when the caller has it already.
        """
        y = np.asarray(y, dtype=np.float64)
        tau = np.asarray(tau, dtype=np.float64)
        if y.shape == (1,) and tau.shape == (1,):
            if jac is None:
                phi = self.phi0 + float(y[0])
                j = self._r12 * math.sin(phi) / math.sqrt(self._k0 - self._k1 * math.cos(phi))
            else:
                j = float(np.asarray(jac, dtype=np.float64).reshape(-1)[0])
            if abs(j) * max_condition >= self.moment_arm_max:
                return np.array((float(tau[0]) / j,))
        jac = (self.jacobian(y) if jac is None else np.asarray(jac, dtype=np.float64))[..., 0]
        condition = self.moment_arm_max / np.abs(jac)
        if np.any(~(condition <= max_condition)):
            raise SingularityError(self._refusal(np.min(np.abs(jac)), float(np.max(condition)), max_condition))
        return np.asarray(tau, dtype=np.float64) / jac

    def _refusal(self, moment_arm: float, condition: float, max_condition: float) -> str:
        return (
            f"{self.name}: force map refused near a singular pose (moment arm {moment_arm:.3g} m, "
            f"condition h_max/|J| = {condition:.3g} > {max_condition:.3g})"
        )

    # --- fused maps ------------------------------------------------------------------------------------------------

    def to_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None = None,
        ydd: FloatArray | None = None,
        tau: FloatArray | None = None,
        max_condition: float = 1e6,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
        """(l, l_dot, l_ddot, f) from one cos/sin evaluation (see the base class)."""
        if (single := self._single_actuator_space(y, yd, ydd, tau, max_condition)) is not None:
            return single
        phi = self.phi0 + as_samples(self.name, y, 1)
        c = np.cos(phi)
        l = np.sqrt(self._k0 - self._k1 * c)
        if yd is None and tau is None:
            return l, None, None, None
        j = self._r12 * np.sin(phi) / l
        f = None
        if tau is not None:
            tau = as_samples(self.name, tau, 1)
            condition = self.moment_arm_max / np.abs(j)
            if np.any(~(condition <= max_condition)):
                raise SingularityError(self._refusal(np.min(np.abs(j)), float(np.max(condition)), max_condition))
            f = tau / j
        ld = ldd = None
        if yd is not None:
            yd = as_samples(self.name, yd, 1)
            ld = j * yd
            if ydd is not None:
                ldd = j * as_samples(self.name, ydd, 1) + (0.5 * self._k1 * c - j * j) / l * yd * yd
        return l, ld, ldd, f

    def to_actuator_space_floats(
        self,
        y: Sequence[float],
        yd: Sequence[float] | None = None,
        ydd: Sequence[float] | None = None,
        tau: Sequence[float] | None = None,
        max_condition: float = 1e6,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class)."""
        (q,) = y
        phi = self.phi0 + q
        c = math.cos(phi)
        l = math.sqrt(self._k0 - self._k1 * c)
        if yd is None and tau is None:
            return (l,), None, None, None
        j = self._r12 * math.sin(phi) / l
        f = None
        if tau is not None:
            if not abs(j) * max_condition >= self.moment_arm_max:
                condition = self.moment_arm_max / abs(j) if j != 0.0 else math.inf
                if not condition <= max_condition:
                    raise SingularityError(self._refusal(abs(j), condition, max_condition))
            f = (tau[0] / j,) if j != 0.0 else (float(np.float64(tau[0]) / j),)  # max_condition = inf: as numpy
        if yd is None:
            return (l,), None, None, f
        (w,) = yd
        ld = (j * w,)
        ldd = None if ydd is None else (j * ydd[0] + (0.5 * self._k1 * c - j * j) / l * w**2,)  # as bias()
        return (l,), ld, ldd, f

    def to_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """(y, y_dot, tau): closed-form FK, then J(y) for y_dot = l_dot / J and tau = J f (see the base class)."""
        if (single := self._single_joint_space(l, ld, f)) is not None:
            return single
        y = self.forward_with_info(l, y_guess)[0]
        if ld is None and f is None:
            return y, None, None
        phi = self.phi0 + y
        j = self._r12 * np.sin(phi) / np.sqrt(self._k0 - self._k1 * np.cos(phi))
        yd = tau = None
        if ld is not None:
            if np.any(j == 0.0):
                raise singular_solve()
            yd = as_samples(self.name, ld, 1) / j
        if f is not None:
            tau = j * as_samples(self.name, f, 1)
        return y, yd, tau

    def to_joint_space_floats(
        self,
        l: Sequence[float],
        ld: Sequence[float] | None = None,
        f: Sequence[float] | None = None,
        y_guess: Sequence[float] | None = None,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class); ``y_guess`` is not needed (closed form)."""
        del y_guess
        (length,) = l
        c = (self._k0 - length * length) / self._k1
        if abs(c) <= 1.0:
            y = self.sign * math.acos(c) - self.phi0
        else:  # unreachable (raises) or outside by rounding only (clipped): the vectorised path decides
            y = float(self.forward_with_info(np.array([[length]]))[0][0, 0])
        if ld is None and f is None:
            return (y,), None, None
        phi = self.phi0 + y
        j = self._r12 * math.sin(phi) / math.sqrt(self._k0 - self._k1 * math.cos(phi))
        yd = tau = None
        if ld is not None:
            if j == 0.0:
                raise singular_solve()
            yd = (ld[0] / j,)
        if f is not None:
            tau = (j * f[0],)
        return (y,), yd, tau

    def torques(self, y: FloatArray, f: FloatArray, jac: FloatArray | None = None) -> FloatArray:
        """tau = J f (``jac`` may pass J(y) when the caller has it already)."""
        jac = self.jacobian(y) if jac is None else np.asarray(jac, dtype=np.float64)
        return jac[..., 0] * np.asarray(f, dtype=np.float64)

    def condition(self, y: FloatArray) -> FloatArray:
        """h_max / |J(y)|; (..., 1) -> (...)."""
        return self.moment_arm_max / np.abs(self.jacobian(y)[..., 0, 0])


def _distance(value: float, interval: tuple[float, float]) -> float:
    return max(interval[0] - value, value - interval[1], 0.0) if math.isfinite(value) else math.inf
