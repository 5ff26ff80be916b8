"""2-SPU+1U: a platform on a universal joint driven by two U-P-S legs (RH5 torso pitch/roll and the wrists).

design/mechanisms.md section 4. The platform turns about the first joint axis w1 (fixed in the base), then about
the second axis w2 (carried by the first joint): R(y) = Rot(w1, y0) Rot(w2, y1). Both axes pass through the base
origin. The models work in the "canonical" frame C = [w1, w2, w1 x w2] of the base, where R(y) = Rx(y0) Ry(y1);
every point is converted once at construction, so the joint axes of the public files are used exactly (the torso's
axes are 3.7e-6 rad off the base axes because the URDF rounds pi/2 to 1.5708).

Leg i: base U-joint centre b_i, platform S-joint centre e_i0 at y = 0; l_i(y) = |R(y) e_i0 - b_i| (4.2).
Jacobian (4.3): l_dot_i = (b_i x e_i) . omega / l_i with omega = W(y) y_dot, W = [x, Rx(y0) y].
Bias (4.4): l_ddot_i = n_i . e_ddot_i + (|e_dot_i|^2 - (n_i . e_dot_i)^2) / l_i at y_ddot = 0.

``UniversalJointPlatform`` holds what the SPU and the ankle's 2-SPRR+1U share: the U-joint kinematics, the Newton
forward kinematics (HyRoDyn's approach, all samples at once) and the closed-form 2x2 statics. Every kernel is plain
arithmetic on either Python floats (the single-sample fast path, shape (2,)) or numpy arrays (any leading shape).
The fused maps ``to_actuator_space`` / ``to_joint_space`` evaluate one pose once: one trig evaluation, then lengths,
Jacobian and bias from the same intermediate quantities (``_fused``), forces and joint rates by the closed-form 2x2
inverse; Newton hands over the Jacobian of its converged iterate, which is exactly J at the returned y.
"""

from __future__ import annotations

import copy
import math
from abc import abstractmethod
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

__all__ = ["Platform2SPU1U", "UniversalJointPlatform"]

_PI = math.pi
_TWO_PI = 2.0 * math.pi

Scalar = Any  # a Python float (single-sample path) or a float64 array (vectorised path)
Vector = tuple[Scalar, Scalar, Scalar]
Trig = tuple[Scalar, Scalar, Scalar, Scalar]  # cos y0, sin y0, cos y1, sin y1


def _cross(a: Vector, b: Vector) -> Vector:
    ax, ay, az = a
    bx, by, bz = b
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


def _trig(y0: float, y1: float) -> Trig:
    return math.cos(y0), math.sin(y0), math.cos(y1), math.sin(y1)


def _trig_array(y: FloatArray) -> Trig:
    y0, y1 = y[..., 0], y[..., 1]
    return np.cos(y0), np.sin(y0), np.cos(y1), np.sin(y1)


def _wrap(y: float) -> float:
    return y if -_PI <= y <= _PI else (y + _PI) % _TWO_PI - _PI


class UniversalJointPlatform(ImmutableModel):
    """Base of the 2-DOF units on a 1U joint; subclasses give the kernels _lengths, _lengths_jacobian and _bias.

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
        self.name = name
        self.kind = kind
        self.joints = tuple(joints)
        self.actuators = tuple(actuators)
        if len(self.joints) != 2 or len(self.actuators) != 2:
            raise ValueError(f"{name}: a {kind} unit has 2 joints and 2 actuators")
        self.limits = limits
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

    # --- construction helpers ------------------------------------------------------------------------------------

    def _canonical(self, point: npt.ArrayLike) -> tuple[float, float, float]:
        """A base-frame vector in the canonical frame (w1, w2, w1 x w2), as Python floats."""
        x, y, z = (self.canonical_frame.T @ np.asarray(point, dtype=np.float64)).tolist()
        return x, y, z

    def _finish(self) -> None:
        """Zero-pose quantities (l0, J(0), its inverse, the working-mode sign), then freeze the model."""
        self.l0 = frozen_array(self.inverse(np.zeros(2)))
        jac0 = self.jacobian(np.zeros(2))
        det0 = float(np.linalg.det(jac0))
        if not abs(det0) > 0.0:
            raise ValueError(f"{self.name}: singular at the zero pose")
        self.jacobian0 = frozen_array(jac0)
        self._l0_floats = tuple(self.l0.tolist())
        self._jinv0 = tuple(np.linalg.inv(jac0).ravel().tolist())
        self._mode = math.copysign(1.0, det0)
        self._freeze()

    def with_newton(self, *, tolerance: float, max_iterations: int) -> UniversalJointPlatform:
        """The same unit with other forward-kinematics stop criteria (a new immutable model; this one is kept)."""
        clone = copy.copy(self)
        object.__setattr__(clone, "tolerance", float(tolerance))
        object.__setattr__(clone, "max_iterations", int(max_iterations))
        return clone

    # --- leg kernels (floats or arrays) ----------------------------------------------------------------------------

    @abstractmethod
    def _lengths(self, trig: Trig) -> tuple[Scalar, Scalar]:
        """(l1, l2) at the pose with ``trig`` = (cos y0, sin y0, cos y1, sin y1)."""

    @abstractmethod
    def _fused(self, trig: Trig, rates: tuple[Scalar, Scalar] | None) -> tuple[Scalar, ...]:
        """(l1, l2, J00, J01, J10, J11, b1, b2) in one pass over the legs; (b1, b2) = J-dot y-dot for y-dot = ``rates``.

        b1, b2 are None when ``rates`` is None (lengths and Jacobian only: Newton, forces, rates).
        """

    def _lengths_jacobian(self, trig: Trig) -> tuple[Scalar, ...]:
        """(l1, l2, J00, J01, J10, J11)."""
        l1, l2, j00, j01, j10, j11, _, _ = self._fused(trig, None)
        return l1, l2, j00, j01, j10, j11

    def _bias(self, trig: Trig, rates: tuple[Scalar, Scalar]) -> tuple[Scalar, Scalar]:
        """(b1, b2) = J-dot y-dot for y-dot = ``rates``."""
        _, _, _, _, _, _, b1, b2 = self._fused(trig, rates)
        return b1, b2

    # --- the contract ----------------------------------------------------------------------------------------------

    def inverse(self, y: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        if y.shape == (2,):
            return np.array(self._lengths(_trig(*y.tolist())))
        return np.stack(self._lengths(_trig_array(as_samples(self.name, y, 2))), axis=-1)

    def jacobian(self, y: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        if y.shape == (2,):
            _, _, j00, j01, j10, j11 = self._lengths_jacobian(_trig(*y.tolist()))
            return np.array(((j00, j01), (j10, j11)))
        y = as_samples(self.name, y, 2)
        _, _, *jac = self._lengths_jacobian(_trig_array(y))
        return np.stack(jac, axis=-1).reshape((*y.shape[:-1], 2, 2))

    def bias(self, y: FloatArray, yd: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=np.float64)
        yd = np.asarray(yd, dtype=np.float64)
        if y.shape == (2,) and yd.shape == (2,):
            w0, w1 = yd.tolist()
            return np.array(self._bias(_trig(*y.tolist()), (w0, w1)))
        y, yd = np.broadcast_arrays(as_samples(self.name, y, 2), as_samples(self.name, yd, 2))
        return np.stack(self._bias(_trig_array(y), (yd[..., 0], yd[..., 1])), axis=-1)

    def forward(self, l: FloatArray, y_guess: FloatArray | None = None) -> FloatArray:
        return self.forward_with_info(l, y_guess)[0]

    # --- fused maps: one pose evaluation per call ------------------------------------------------------------------

    def to_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None = None,
        ydd: FloatArray | None = None,
        tau: FloatArray | None = None,
        max_condition: float = 1e6,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
        """(l, l_dot, l_ddot, f) from one trig evaluation and one pass over the legs (see the base class)."""
        if (single := self._single_actuator_space(y, yd, ydd, tau, max_condition)) is not None:
            return single
        y = as_samples(self.name, y, 2)
        trig = _trig_array(y)
        if yd is None and tau is None:
            return np.stack(self._lengths(trig), axis=-1), None, None, None
        if yd is not None:
            yd = as_samples(self.name, yd, 2)
        rates = None if yd is None or ydd is None else (yd[..., 0], yd[..., 1])  # the bias only for l_ddot
        l1, l2, j00, j01, j10, j11, b1, b2 = self._fused(trig, rates)
        f = None
        if tau is not None:
            tau = as_samples(self.name, tau, 2)
            condition = _condition(j00, j01, j10, j11)
            if np.any(~(condition <= max_condition)):
                raise SingularityError(self._refusal(float(np.max(condition)), max_condition))
            det = j00 * j11 - j01 * j10
            t0, t1 = tau[..., 0], tau[..., 1]
            f = np.stack(((j11 * t0 - j10 * t1) / det, (j00 * t1 - j01 * t0) / det), axis=-1)
        ld = ldd = None
        if yd is not None:
            w0, w1 = yd[..., 0], yd[..., 1]
            ld = np.stack((j00 * w0 + j01 * w1, j10 * w0 + j11 * w1), axis=-1)
            if ydd is not None:
                ydd = as_samples(self.name, ydd, 2)
                a0, a1 = ydd[..., 0], ydd[..., 1]
                ldd = np.stack((j00 * a0 + j01 * a1 + b1, j10 * a0 + j11 * a1 + b2), axis=-1)
        return np.stack((l1, l2), axis=-1), ld, ldd, f

    def to_actuator_space_floats(
        self,
        y: Sequence[float],
        yd: Sequence[float] | None = None,
        ydd: Sequence[float] | None = None,
        tau: Sequence[float] | None = None,
        max_condition: float = 1e6,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class)."""
        y0, y1 = y
        trig = (math.cos(y0), math.sin(y0), math.cos(y1), math.sin(y1))
        if yd is None:
            if tau is None:
                return self._lengths(trig), None, None, None
            l1, l2, j00, j01, j10, j11, _, _ = self._fused(trig, None)
            ld = ldd = None
        else:
            w0, w1 = yd
            if ydd is None:  # no bias needed
                l1, l2, j00, j01, j10, j11, _, _ = self._fused(trig, None)
                ldd = None
            else:
                l1, l2, j00, j01, j10, j11, b1, b2 = self._fused(trig, (w0, w1))
                a0, a1 = ydd
                ldd = (j00 * a0 + j01 * a1 + b1, j10 * a0 + j11 * a1 + b2)
            ld = (j00 * w0 + j01 * w1, j10 * w0 + j11 * w1)
        if tau is None:
            return (l1, l2), ld, ldd, None
        det = j00 * j11 - j01 * j10
        frob = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
        disc = frob * frob - 4.0 * det * det
        disc = math.sqrt(0.0 if disc < 0.0 else disc)  # = max(disc, 0.0) as in forces(), NaN kept
        cond = (frob + disc) / (2.0 * abs(det)) if det != 0.0 else math.inf
        if not cond <= max_condition:
            raise SingularityError(self._refusal(cond, max_condition))
        t0, t1 = tau
        return (l1, l2), ld, ldd, ((j11 * t0 - j10 * t1) / det, (j00 * t1 - j01 * t0) / det)

    def to_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """(y, y_dot, tau): Newton FK, then the converged iterate's J (= J(y)) for y_dot = J^-1 l_dot, tau = J^T f."""
        if (single := self._single_joint_space(l, ld, f, y_guess)) is not None:
            return single
        l = as_samples(self.name, l, 2)
        flat = l.reshape(-1, 2)
        guess = None if y_guess is None else np.broadcast_to(as_samples(self.name, y_guess, 2), l.shape).reshape(-1, 2)
        need_jac = ld is not None or f is not None
        y, _, jac = self._newton_batch(flat, guess, with_jacobian=need_jac)
        y = y.reshape(l.shape)
        if not need_jac:
            return y, None, None
        j00, j01, j10, j11 = (j.reshape(l.shape[:-1]) for j in jac)
        yd = tau = None
        if ld is not None:
            ld = as_samples(self.name, ld, 2)
            det = j00 * j11 - j01 * j10
            if np.any(det == 0.0):
                raise singular_solve()
            u0, u1 = ld[..., 0], ld[..., 1]
            yd = np.stack(((j11 * u0 - j01 * u1) / det, (j00 * u1 - j10 * u0) / det), axis=-1)
        if f is not None:
            f = as_samples(self.name, f, 2)
            f0, f1 = f[..., 0], f[..., 1]
            tau = np.stack((j00 * f0 + j10 * f1, j01 * f0 + j11 * f1), axis=-1)
        return y, yd, tau

    def to_joint_space_floats(
        self,
        l: Sequence[float],
        ld: Sequence[float] | None = None,
        f: Sequence[float] | None = None,
        y_guess: Sequence[float] | None = None,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class)."""
        t0, t1 = l
        need_jac = ld is not None or f is not None
        y0, y1, _, jac = self._newton_floats(t0, t1, y_guess, need_jac)
        if not need_jac:
            return (y0, y1), None, None
        j00, j01, j10, j11 = jac
        yd = tau = None
        if ld is not None:
            det = j00 * j11 - j01 * j10
            if det == 0.0:
                raise singular_solve()
            u0, u1 = ld
            yd = ((j11 * u0 - j01 * u1) / det, (j00 * u1 - j10 * u0) / det)
        if f is not None:
            f0, f1 = f
            tau = (j00 * f0 + j10 * f1, j01 * f0 + j11 * f1)
        return (y0, y1), yd, tau

    def forward_with_info(self, l: FloatArray, y_guess: FloatArray | None = None) -> tuple[FloatArray, Any]:
        """Joints y(l) and the Newton iteration count per sample (an int, or an int array of the leading shape)."""
        l = np.asarray(l, dtype=np.float64)
        if l.shape == (2,) and (y_guess is None or np.shape(y_guess) == (2,)):
            return self._newton_single(l, y_guess)
        l = as_samples(self.name, l, 2)
        flat = l.reshape(-1, 2)
        guess = None if y_guess is None else np.broadcast_to(as_samples(self.name, y_guess, 2), l.shape).reshape(-1, 2)
        y, iterations, _ = self._newton_batch(flat, guess)
        return y.reshape(l.shape), iterations.reshape(l.shape[:-1])

    def forces(
        self, y: FloatArray, tau: FloatArray, max_condition: float = 1e6, jac: FloatArray | None = None
    ) -> FloatArray:
        """f = J^-T tau in closed form; refuses (SingularityError) where cond_2(J) > ``max_condition``.

        ``jac`` may pass J(y) when the caller has it already.
        """
        y = np.asarray(y, dtype=np.float64)
        tau = np.asarray(tau, dtype=np.float64)
        if y.shape == (2,) and tau.shape == (2,):
            if jac is None:
                _, _, j00, j01, j10, j11 = self._lengths_jacobian(_trig(*y.tolist()))
            else:
                (j00, j01), (j10, j11) = np.asarray(jac, dtype=np.float64).tolist()
            det = j00 * j11 - j01 * j10
            frob = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
            disc = math.sqrt(max(frob * frob - 4.0 * det * det, 0.0))
            cond = (frob + disc) / (2.0 * abs(det)) if det != 0.0 else math.inf
            if not cond <= max_condition:
                raise SingularityError(self._refusal(cond, max_condition))
            t0, t1 = tau.tolist()
            return np.array(((j11 * t0 - j10 * t1) / det, (j00 * t1 - j01 * t0) / det))
        jac = self.jacobian(y) if jac is None else np.asarray(jac, dtype=np.float64)
        j00, j01, j10, j11 = jac[..., 0, 0], jac[..., 0, 1], jac[..., 1, 0], jac[..., 1, 1]
        condition = _condition(j00, j01, j10, j11)
        if np.any(~(condition <= max_condition)):
            raise SingularityError(self._refusal(float(np.max(condition)), max_condition))
        det = j00 * j11 - j01 * j10
        t0, t1 = tau[..., 0], tau[..., 1]
        return np.stack(((j11 * t0 - j10 * t1) / det, (j00 * t1 - j01 * t0) / det), axis=-1)

    def _refusal(self, condition: float, max_condition: float) -> str:
        return f"{self.name}: force map refused near a singular pose (cond(J) = {condition:.3g} > {max_condition:.3g})"

    def torques(self, y: FloatArray, f: FloatArray, jac: FloatArray | None = None) -> FloatArray:
        """tau = J^T f (``jac`` may pass J(y) when the caller has it already)."""
        jac = self.jacobian(y) if jac is None else np.asarray(jac, dtype=np.float64)
        f = np.asarray(f, dtype=np.float64)
        f0, f1 = f[..., 0], f[..., 1]
        return np.stack((jac[..., 0, 0] * f0 + jac[..., 1, 0] * f1, jac[..., 0, 1] * f0 + jac[..., 1, 1] * f1), axis=-1)

    def condition(self, y: FloatArray) -> FloatArray:
        """The 2-norm condition number of J(y); (..., 2) -> (...)."""
        jac = self.jacobian(y)
        return np.asarray(_condition(jac[..., 0, 0], jac[..., 0, 1], jac[..., 1, 0], jac[..., 1, 1]))

    # --- Newton forward kinematics ---------------------------------------------------------------------------------

    def _cold_start(self, d0: Scalar, d1: Scalar) -> tuple[Scalar, Scalar]:
        a, b, c, d = self._jinv0
        return a * d0 + b * d1, c * d0 + d * d1

    def _fail(self, count: int, total: int, residual: float, where: FloatArray, why: str) -> ForwardKinematicsError:
        return ForwardKinematicsError(
            f"{self.name}: forward kinematics failed for {count} of {total} sample(s): {why} "
            f"(max residual {residual:.3g} m after {self.max_iterations} Newton iterations at most; "
            f"first failing l = {np.array2string(np.asarray(where), precision=6)} m)"
        )

    def _newton_single(self, l: FloatArray, y_guess: FloatArray | None) -> tuple[FloatArray, int]:
        t0, t1 = l.tolist()
        guess = None if y_guess is None else np.asarray(y_guess, dtype=np.float64).tolist()
        y0, y1, iteration, _ = self._newton_floats(t0, t1, guess, False)
        return np.array((y0, y1)), iteration

    def _newton_floats(
        self, t0: float, t1: float, y_guess: Sequence[float] | None, with_jacobian: bool
    ) -> tuple[float, float, int, tuple[float, float, float, float] | None]:
        """Newton on Python floats: (y0, y1) wrapped to [-pi, pi], the iteration count, and J at exactly that y.

        J is the converged iterate's (no step follows it), re-evaluated only where wrapping moved y by 2 pi; None
        unless ``with_jacobian``.
        """
        if y_guess is None:
            l00, l01 = self._l0_floats
            y0, y1 = self._cold_start(t0 - l00, t1 - l01)
        else:
            y0, y1 = y_guess
        tol, cap, max_step = self.tolerance, self.max_iterations, self.max_step
        residual = math.inf
        for iteration in range(cap + 1):
            l1, l2, j00, j01, j10, j11, _, _ = self._fused(_trig(y0, y1), None)
            r0, r1 = l1 - t0, l2 - t1
            residual = max(abs(r0), abs(r1))
            det = j00 * j11 - j01 * j10
            if residual <= tol:
                if det * self._mode <= 0.0:
                    raise self._fail(
                        1, 1, residual, np.array((t0, t1)), "converged outside the working mode of the zero pose"
                    )
                w0, w1 = _wrap(y0), _wrap(y1)
                if not with_jacobian:
                    return w0, w1, iteration, None
                if w0 != y0 or w1 != y1:
                    _, _, j00, j01, j10, j11 = self._lengths_jacobian(_trig(w0, w1))
                return w0, w1, iteration, (j00, j01, j10, j11)
            if iteration == cap or not (math.isfinite(residual) and det != 0.0):
                break
            d0 = (j11 * r0 - j01 * r1) / det
            d1 = (j00 * r1 - j10 * r0) / det
            step = max(abs(d0), abs(d1))
            if step > max_step:
                d0, d1 = d0 * (max_step / step), d1 * (max_step / step)
            y0 -= d0
            y1 -= d1
        raise self._fail(1, 1, residual, np.array((t0, t1)), "Newton did not converge (lengths not assemblable?)")

    def _newton_batch(
        self, l: FloatArray, y_guess: FloatArray | None, with_jacobian: bool = False
    ) -> tuple[FloatArray, npt.NDArray[np.int64], tuple[FloatArray, ...] | None]:
        """Newton on (n, 2) arrays: y, iterations, and (J00, J01, J10, J11) at exactly y if ``with_jacobian``."""
        n = l.shape[0]
        jac = tuple(np.empty(n) for _ in range(4)) if with_jacobian else None
        if y_guess is None:
            y = np.stack(self._cold_start(l[:, 0] - self.l0[0], l[:, 1] - self.l0[1]), axis=-1)
        else:
            y = np.array(y_guess, dtype=np.float64)
        iterations = np.full(n, -1, dtype=np.int64)
        active = np.arange(n)
        ya, la = y, l
        residual = np.zeros(0)
        for iteration in range(self.max_iterations + 1):
            l1, l2, j00, j01, j10, j11, _, _ = self._fused(_trig_array(ya), None)
            r0, r1 = l1 - la[:, 0], l2 - la[:, 1]
            residual = np.maximum(np.abs(r0), np.abs(r1))
            det = j00 * j11 - j01 * j10
            done = residual <= self.tolerance
            if np.any(done):
                wrong_mode = done & (det * self._mode <= 0.0)
                if np.any(wrong_mode):
                    bad = active[wrong_mode]
                    raise self._fail(
                        bad.size, n, float(residual[wrong_mode].max()), l[bad[0]], "converged outside the working mode"
                    )
                y[active[done]] = ya[done]
                iterations[active[done]] = iteration
                if jac is not None:
                    for store, value in zip(jac, (j00, j01, j10, j11), strict=True):
                        store[active[done]] = value[done]
                keep = ~done
                active, ya, la = active[keep], ya[keep], la[keep]
                r0, r1, det, residual = r0[keep], r1[keep], det[keep], residual[keep]
                j00, j01, j10, j11 = j00[keep], j01[keep], j10[keep], j11[keep]
            if active.size == 0 or iteration == self.max_iterations:
                break
            with np.errstate(divide="ignore", invalid="ignore"):
                d0 = (j11 * r0 - j01 * r1) / det
                d1 = (j00 * r1 - j10 * r0) / det
                step = np.maximum(np.abs(d0), np.abs(d1))
                scale = np.where(step > self.max_step, self.max_step / step, 1.0)
            ya = ya - np.stack((d0 * scale, d1 * scale), axis=-1)
        if active.size:
            finite = residual[np.isfinite(residual)]
            worst = float(finite.max()) if finite.size else math.nan
            raise self._fail(active.size, n, worst, l[active[0]], "Newton did not converge (lengths not assemblable?)")
        outside = np.abs(y) > _PI
        if np.any(outside):
            y = np.where(outside, (y + _PI) % _TWO_PI - _PI, y)
            if jac is not None:  # J of the converged iterate is J(y) only where wrapping did not move y
                moved = np.flatnonzero(np.any(outside, axis=-1))
                _, _, *again = self._lengths_jacobian(_trig_array(y[moved]))
                for store, value in zip(jac, again, strict=True):
                    store[moved] = value
        return y, iterations, jac


def _condition(j00: Scalar, j01: Scalar, j10: Scalar, j11: Scalar) -> Any:
    """cond_2 of [[j00, j01], [j10, j11]] = sigma_max^2 / |det| (closed form of the 2x2 singular values)."""
    frob = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
    det = np.abs(j00 * j11 - j01 * j10)
    disc = np.sqrt(np.maximum(frob * frob - 4.0 * det * det, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det > 0.0, (frob + disc) / (2.0 * det), np.inf)


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
        self._legs = tuple(self._canonical(b) + self._canonical(e) for b, e in zip(base, platform, strict=True))
        self._finish()

    def _lengths(self, trig: Trig) -> tuple[Scalar, Scalar]:
        c0, s0, c1, s1 = trig
        out = []
        for bx, by, bz, ex, ey, ez in self._legs:
            px = c1 * ex + s1 * ez  # e = Rx(y0) Ry(y1) e0
            wz = c1 * ez - s1 * ex
            py = c0 * ey - s0 * wz
            pz = s0 * ey + c0 * wz
            dx, dy, dz = px - bx, py - by, pz - bz
            out.append((dx * dx + dy * dy + dz * dz) ** 0.5)
        return out[0], out[1]

    def _fused(self, trig: Trig, rates: tuple[Scalar, Scalar] | None) -> tuple[Scalar, ...]:
        c0, s0, c1, s1 = trig
        if rates is not None:
            w0, w1 = rates
            ox, oy, oz = w0, c0 * w1, s0 * w1  # omega = W y_dot
            ay, az = -s0 * w0 * w1, c0 * w0 * w1  # alpha = W-dot y_dot = y0d y1d (x cross Rx(y0) y); alpha_x = 0
        out: list[Scalar] = []
        for bx, by, bz, ex, ey, ez in self._legs:
            px = c1 * ex + s1 * ez
            wz = c1 * ez - s1 * ex
            py = c0 * ey - s0 * wz
            pz = s0 * ey + c0 * wz
            dx, dy, dz = px - bx, py - by, pz - bz
            l = (dx * dx + dy * dy + dz * dz) ** 0.5
            my, mz = bz * px - bx * pz, bx * py - by * px  # b x e; e x n = (b x e) / l
            out += (l, (by * pz - bz * py) / l, (c0 * my + s0 * mz) / l)  # W = [x, Rx(y0) y] = [(1,0,0), (0,c0,s0)]
            if rates is None:
                out.append(None)
                continue
            vx, vy, vz = oy * pz - oz * py, oz * px - ox * pz, ox * py - oy * px  # e_dot = omega x e
            qx, qy, qz = oy * vz - oz * vy, oz * vx - ox * vz, ox * vy - oy * vx  # omega x e_dot
            ndv = (dx * vx + dy * vy + dz * vz) / l
            nda = (dx * ((ay * pz - az * py) + qx) + dy * (az * px + qy) + dz * (-ay * px + qz)) / l  # n . e_ddot
            out.append(nda + (vx * vx + vy * vy + vz * vz - ndv * ndv) / l)
        return out[0], out[4], out[1], out[2], out[5], out[6], out[3], out[7]
