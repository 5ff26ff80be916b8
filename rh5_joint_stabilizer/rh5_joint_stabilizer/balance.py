"""Optional task-space correction: an ankle strategy against the measured tilt of the floating base.

Joint-space control cannot see the robot pivoting about a foot edge after an impact (the
paper's main failure on hardware). When the base orientation is measured (in simulation:
``sim/base_pose``), this adds to both ankles' roll and pitch references the rotation that
turns the base back upright about the ankle axes: for a foot resting on the ground,
moving an ankle joint by dq rotates everything above it by -dq about the joint axis, so
dq = gain * (e . axis) cancels a base tilt e (world rotation vector) for gain = 1.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from rh5_joint_stabilizer.reference import ReferenceSample
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_INDEX
from rh5_msgs_py.realtime import LatestValue

ANKLE_JOINTS = ("LLAnkleRoll", "LLAnklePitch", "LRAnkleRoll", "LRAnklePitch")


def _quaternion_to_rotation_vector(xyzw: FloatArray) -> FloatArray:
    """Rotation vector (axis * angle, angle <= pi) of a unit quaternion (x, y, z, w): Pinocchio's ``log3``."""
    return pin.log3(pin.Quaternion(np.asarray(xyzw, dtype=np.float64)).normalized())


def ankle_axes_world() -> dict[str, FloatArray]:
    """World directions of the four ankle joint axes in the standing pose (from the RH5 model)."""
    from rh5_hyrodyn_mapper.model import build_model, standing_configuration  # noqa: PLC0415

    model = build_model(free_flyer=True)
    data = model.createData()
    pin.forwardKinematics(model, data, standing_configuration(model))
    axes = {}
    for name in ANKLE_JOINTS:
        joint_id = model.getJointId(name)
        motion = model.joints[joint_id].shortname()
        local = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}
        if motion.startswith("JointModelR") and motion[-1] in local:
            axis_local = local[motion[-1]]
        else:  # revolute about an arbitrary axis
            axis_local = np.asarray(model.joints[joint_id].extract().axis, dtype=np.float64)
        axes[name] = data.oMi[joint_id].rotation @ axis_local
    return axes


class AnkleBalanceCorrection:
    """Adds gain * (base tilt . ankle axis) to the ankle references while a fresh base orientation exists."""

    def __init__(self, gain: float, max_correction: float, timeout_ns: int, axes: dict[str, FloatArray]) -> None:
        self.gain = gain
        self.max_correction = max_correction
        self.timeout_ns = timeout_ns
        self._index = np.array([JOINT_INDEX[j] for j in ANKLE_JOINTS])
        self._axes = np.array([axes[j] for j in ANKLE_JOINTS])
        self.base_orientation: LatestValue[FloatArray] = LatestValue()
        self.active = False

    def offsets(self, tilt: FloatArray) -> FloatArray:
        """Ankle offsets [rad] (ANKLE_JOINTS order) that turn a base tilt ``tilt`` (rotation vector) back."""
        return np.clip(self.gain * (self._axes @ tilt), -self.max_correction, self.max_correction)

    def __call__(self, reference: ReferenceSample) -> ReferenceSample:
        """The reference with the ankle offsets added (unchanged without a fresh base orientation)."""
        quaternion, _, version = self.base_orientation.try_get()
        age = self.base_orientation.age_ns()
        self.active = version > 0 and quaternion is not None and age is not None and age <= self.timeout_ns
        if not self.active:
            return reference
        position = reference.position.copy()
        position[self._index] += self.offsets(_quaternion_to_rotation_vector(quaternion))
        return ReferenceSample(position, reference.velocity, reference.effort)
