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

The maps (T, T^-1, T^-T and T^T over the non-zero entries of each row) run in the C kernels (``unit_maps.c``, kind
LINEAR), as every other unit's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray

from . import kernels
from .base import ActuatorLimits, ImmutableModel, actuator_limits, frozen_array

__all__ = ["HEAD_TRANSMISSION", "LinearTransmission", "SerialJoint", "transmission_limits"]

HEAD_TRANSMISSION: npt.NDArray[np.float64] = frozen_array([[1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 1.0]])
"""Head actuators from (HeadPitch, HeadRoll, HeadYaw): rh5_public_model/hyrodyn/Head.urdf, transmission "Head"."""


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
        super().__init__(name, kind, joints, actuators, limits)
        m = len(self.joints)
        t = np.asarray(matrix, dtype=np.float64)
        if t.shape != (m, m) or len(self.actuators) != m:
            raise ValueError(f"{name}: expected a {m} x {m} transmission for {m} joints and actuators")
        singular = np.linalg.svd(t, compute_uv=False)
        if not singular[-1] > 0.0:
            raise ValueError(f"{name}: singular transmission")
        self.matrix = frozen_array(t)
        self.inverse_matrix = frozen_array(np.linalg.inv(t))
        self.condition_number = float(singular[0] / singular[-1])
        if m > kernels.MAX_DOF:
            raise ValueError(f"{name}: the kernels map transmissions of at most {kernels.MAX_DOF} joints")
        self.l0 = frozen_array(np.zeros(m))
        self._freeze()

    def kernel_constants(self) -> tuple[int, list[float]]:
        """The kernel row: a pass-through (COPY) for T = I, else cond(T), T and T^-1 as 3 x 3 (zero-padded)."""
        m = self.dof
        if np.array_equal(self.matrix, np.eye(m)):
            return kernels.KIND_COPY, []
        square = np.zeros((2, kernels.MAX_DOF, kernels.MAX_DOF))
        square[0, :m, :m], square[1, :m, :m] = self.matrix, self.inverse_matrix
        return kernels.KIND_LINEAR, [self.condition_number, *square.ravel().tolist()]

    def _refusal(self, conditions: FloatArray, max_condition: float) -> str:
        del conditions  # cond(T), the same everywhere
        return f"{self.name}: force map refused (cond(T) = {self.condition_number:.3g} > {max_condition:.3g})"


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
