"""Linear (constant-Jacobian) submechanisms: rotary joints passed through, and the head's transmission.

So the whole-robot assembly can treat every submechanism alike, the rotary joints are "submechanisms" too:
l = T y, J = T, bias = 0, y = T^-1 l, f = T^-T tau (HyRoDyn gives serial types the identity base class).

* ``serial`` (BodyYaw, shoulders, elbows, wrist rolls, Hip1, Hip2): T = [1]. The actuator coordinate is the joint
  angle; the limits are the joint's (rad, rad/s, Nm) from the robot model (``model.joint_limits()``).
* ``transmission`` (Head): the public model's ``hyrodyn/Head.urdf`` declares a ``MultiJointLinearTransmission``:
  Head_Act1 = HeadPitch + HeadRoll, Head_Act2 = HeadPitch - HeadRoll, Head_Act3 = HeadYaw (multipliers +-1,
  offsets 0) - a differential for pitch/roll, not an identity. With the joint order (HeadPitch, HeadRoll, HeadYaw)
  T = [[1, 1, 0], [1, -1, 0], [0, 0, 1]]. Head.urdf gives all three Head_Act joints HeadPitch's <limit> (-20..15 deg,
  9.8 Nm), which cannot be the drives' (Act3 drives the +-90 deg yaw), so the actuator limits are the joint limits
  mapped through T: the smallest stroke box containing T(joint box), speed sum_j |T_ij| v_j, and force
  sum_j |(T^-1)_ji| tau_j (the actuator force that the joint torque limits can demand).

The fused maps ``to_actuator_space`` / ``to_joint_space`` apply T, T^-1, T^-T and T^T directly (copies for T = I);
on one sample they work on Python floats, summing only the non-zero entries of each row.
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
    ImmutableModel,
    SingularityError,
    actuator_limits,
    as_samples,
    frozen_array,
)

__all__ = ["HEAD_TRANSMISSION", "LinearTransmission", "SerialJoint", "transmission_limits"]

HEAD_TRANSMISSION: npt.NDArray[np.float64] = frozen_array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
"""Head actuators from (HeadPitch, HeadRoll, HeadYaw): rh5_public_model/hyrodyn/Head.urdf, transmission "Head"."""

_Rows = tuple[tuple[tuple[int, float], ...], ...]  # per output: the (input index, factor) pairs with factor != 0


def _sparse_rows(matrix: FloatArray) -> _Rows:
    return tuple(tuple((j, float(t)) for j, t in enumerate(row) if t != 0.0) for row in matrix.tolist())


def _apply(rows: _Rows, x: Sequence[float]) -> list[float]:
    """``matrix @ x`` on Python floats, over the non-zero entries only."""
    out = []
    for row in rows:
        total = 0.0
        for j, t in row:
            total += t * x[j]
        out.append(total)
    return out


class LinearTransmission(ImmutableModel):
    """l = T y with a constant invertible matrix T (m x m).

    Args:
        name, kind, joints, actuators: as in rh5_msgs_py.names.SUBMECHANISMS.
        matrix: T, actuator coordinates from joint angles.
        limits: ActuatorLimits in actuator units (rad, rad/s, Nm for RH5's rotary drives).
    """

    def __init__(
        self,
        name: str,
        kind: str,
        joints: Sequence[str],
        actuators: Sequence[str],
        *,
        matrix: npt.ArrayLike,
        limits: ActuatorLimits,
    ) -> None:
        self.name = name
        self.kind = kind
        self.joints = tuple(joints)
        self.actuators = tuple(actuators)
        m = len(self.joints)
        t = np.asarray(matrix, dtype=np.float64)
        if t.shape != (m, m) or len(self.actuators) != m:
            raise ValueError(f"{name}: expected a {m} x {m} transmission for {m} joints and actuators")
        singular = np.linalg.svd(t, compute_uv=False)
        if not singular[-1] > 0.0:
            raise ValueError(f"{name}: singular transmission")
        self.limits = limits
        self.matrix = frozen_array(t)
        self.inverse_matrix = frozen_array(np.linalg.inv(t))
        self.condition_number = float(singular[0] / singular[-1])
        self.l0 = frozen_array(np.zeros(m))
        self._identity = bool(np.array_equal(t, np.eye(m)))
        self._rows = _sparse_rows(self.matrix)  # l = T y
        self._inverse_rows = _sparse_rows(self.inverse_matrix)  # y = T^-1 l
        self._force_rows = _sparse_rows(self.inverse_matrix.T)  # f = T^-T tau
        self._torque_rows = _sparse_rows(self.matrix.T)  # tau = T^T f
        self._freeze()

    def inverse(self, y: FloatArray) -> FloatArray:
        y = as_samples(self.name, y, self.dof)
        return y.copy() if self._identity else y @ self.matrix.T

    def jacobian(self, y: FloatArray) -> FloatArray:
        y = as_samples(self.name, y, self.dof)
        if y.ndim == 1:
            return self.matrix.copy()
        return np.broadcast_to(self.matrix, (*y.shape[:-1], self.dof, self.dof)).copy()

    def bias(self, y: FloatArray, yd: FloatArray) -> FloatArray:
        y = as_samples(self.name, y, self.dof)
        yd = as_samples(self.name, yd, self.dof)
        return np.zeros(y.shape if y.shape == yd.shape else np.broadcast_shapes(y.shape, yd.shape))

    def forward(self, l: FloatArray, y_guess: FloatArray | None = None) -> FloatArray:
        del y_guess
        l = as_samples(self.name, l, self.dof)
        return l.copy() if self._identity else l @ self.inverse_matrix.T

    def forward_with_info(self, l: FloatArray, y_guess: FloatArray | None = None) -> tuple[FloatArray, Any]:
        """Joints y(l) and the iteration count (always 0), shaped like the other models' answers."""
        y = self.forward(l, y_guess)
        return y, (0 if y.ndim == 1 else np.zeros(y.shape[:-1], dtype=np.int64))

    def forces(
        self, y: FloatArray, tau: FloatArray, max_condition: float = 1e6, jac: FloatArray | None = None
    ) -> FloatArray:
        """f = T^-T tau; refused only if cond(T) itself exceeds ``max_condition`` (``jac`` is not needed: J = T)."""
        del jac
        as_samples(self.name, y, self.dof)
        self._refuse_forces(max_condition)
        tau = as_samples(self.name, tau, self.dof)
        return tau.copy() if self._identity else tau @ self.inverse_matrix

    def torques(self, y: FloatArray, f: FloatArray, jac: FloatArray | None = None) -> FloatArray:
        """tau = T^T f (``jac`` is not needed: J = T)."""
        del jac
        as_samples(self.name, y, self.dof)
        f = as_samples(self.name, f, self.dof)
        return f.copy() if self._identity else f @ self.matrix

    def _refuse_forces(self, max_condition: float) -> None:
        if not self.condition_number <= max_condition:
            msg = f"{self.name}: force map refused (cond(T) = {self.condition_number:.3g} > {max_condition:.3g})"
            raise SingularityError(msg)

    def _times(self, x: FloatArray) -> FloatArray:
        return x.copy() if self._identity else x @ self.matrix.T

    def to_actuator_space(
        self,
        y: FloatArray,
        yd: FloatArray | None = None,
        ydd: FloatArray | None = None,
        tau: FloatArray | None = None,
        max_condition: float = 1e6,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None, FloatArray | None]:
        """(T y, T y_dot, T y_ddot, T^-T tau) (bias 0; see the base class)."""
        m = self.dof
        if (single := self._single_actuator_space(y, yd, ydd, tau, max_condition)) is not None:
            return single
        y = as_samples(self.name, y, m)
        yd, ydd, tau = (None if x is None else as_samples(self.name, x, m) for x in (yd, ydd, tau))
        if any(x is not None and x.shape != y.shape for x in (yd, ydd, tau)):  # broadcasting: the composed maps
            return super().to_actuator_space(y, yd, ydd, tau, max_condition)
        f = None
        if tau is not None:
            self._refuse_forces(max_condition)
            f = tau.copy() if self._identity else tau @ self.inverse_matrix
        if yd is None:
            return self._times(y), None, None, f
        return self._times(y), self._times(yd), (None if ydd is None else self._times(ydd)), f

    def to_actuator_space_floats(
        self,
        y: Sequence[float],
        yd: Sequence[float] | None = None,
        ydd: Sequence[float] | None = None,
        tau: Sequence[float] | None = None,
        max_condition: float = 1e6,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class)."""
        f = None
        if tau is not None:
            self._refuse_forces(max_condition)
            f = list(tau) if self._identity else _apply(self._force_rows, tau)
        if self._identity:
            if yd is None:
                return list(y), None, None, f
            return list(y), list(yd), (None if ydd is None else list(ydd)), f
        rows = self._rows
        if yd is None:
            return _apply(rows, y), None, None, f
        return _apply(rows, y), _apply(rows, yd), (None if ydd is None else _apply(rows, ydd)), f

    def to_joint_space(
        self,
        l: FloatArray,
        ld: FloatArray | None = None,
        f: FloatArray | None = None,
        y_guess: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        """(T^-1 l, T^-1 l_dot, T^T f) (see the base class; ``y_guess`` is not needed)."""
        m = self.dof
        if (single := self._single_joint_space(l, ld, f)) is not None:
            return single
        l = as_samples(self.name, l, m)
        ld, f = (None if x is None else as_samples(self.name, x, m) for x in (ld, f))
        if any(x is not None and x.shape != l.shape for x in (ld, f)):  # broadcasting: the composed maps
            return super().to_joint_space(l, ld, f, y_guess)
        if self._identity:
            return l.copy(), (None if ld is None else ld.copy()), (None if f is None else f.copy())
        inverse = self.inverse_matrix.T
        return l @ inverse, (None if ld is None else ld @ inverse), (None if f is None else f @ self.matrix)

    def to_joint_space_floats(
        self,
        l: Sequence[float],
        ld: Sequence[float] | None = None,
        f: Sequence[float] | None = None,
        y_guess: Sequence[float] | None = None,
    ) -> tuple[Sequence[float], Sequence[float] | None, Sequence[float] | None]:
        """One sample on Python floats (see the base class; ``y_guess`` is not needed)."""
        del y_guess
        if self._identity:
            return list(l), (None if ld is None else list(ld)), (None if f is None else list(f))
        rows = self._inverse_rows
        return (
            _apply(rows, l),
            None if ld is None else _apply(rows, ld),
            None if f is None else _apply(self._torque_rows, f),
        )

    def condition(self, y: FloatArray) -> FloatArray:
        """cond(T), constant; (..., m) -> (...)."""
        y = as_samples(self.name, y, self.dof)
        return np.full(y.shape[:-1], self.condition_number)


class SerialJoint(LinearTransmission):
    """A rotary joint passed through unchanged (l = y): kind "serial", one joint = one actuator of the same name."""

    def __init__(self, name: str, joints: Sequence[str], actuators: Sequence[str], *, limits: ActuatorLimits) -> None:
        super().__init__(name, "serial", joints, actuators, matrix=np.eye(len(tuple(joints))), limits=limits)


def transmission_limits(
    matrix: npt.ArrayLike,
    position_lower: npt.ArrayLike,
    position_upper: npt.ArrayLike,
    velocity_max: npt.ArrayLike,
    torque_max: npt.ArrayLike,
) -> ActuatorLimits:
    """Actuator limits of l = T y implied by joint limits (box image of the joint box; see the module docstring)."""
    t = np.asarray(matrix, dtype=np.float64)
    lo, hi = np.asarray(position_lower, dtype=np.float64), np.asarray(position_upper, dtype=np.float64)
    length_min = np.minimum(t * lo, t * hi).sum(axis=1)
    length_max = np.maximum(t * lo, t * hi).sum(axis=1)
    velocity = np.abs(t) @ np.asarray(velocity_max, dtype=np.float64)
    force = np.abs(np.linalg.inv(t)).T @ np.asarray(torque_max, dtype=np.float64)
    if not (np.all(np.isfinite(length_min)) and math.isfinite(float(force.sum()))):
        raise ValueError("transmission limits must be finite")
    return actuator_limits(length_min, length_max, velocity, force)
