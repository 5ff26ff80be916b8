"""The project's RH5 robot model: parameter file, URDF generator and the pinocchio model built from it.

Names resolve lazily, so ``from rh5_hyrodyn_mapper.model.urdf import generate_urdf`` does not import pinocchio.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .robot import (
        CONTACT_FRAMES,
        JointLimits,
        RobotModel,
        build_model,
        joint_limits,
        model_hash,
        q_index,
        robot_model,
        standing_configuration,
        v_index,
    )
    from .urdf import generate_urdf, load_parameters

_EXPORTS = {
    "generate_urdf": "urdf",
    "load_parameters": "urdf",
    "CONTACT_FRAMES": "robot",
    "JointLimits": "robot",
    "RobotModel": "robot",
    "build_model": "robot",
    "joint_limits": "robot",
    "model_hash": "robot",
    "q_index": "robot",
    "robot_model": "robot",
    "standing_configuration": "robot",
    "v_index": "robot",
}
__all__ = [
    "CONTACT_FRAMES",
    "JointLimits",
    "RobotModel",
    "build_model",
    "generate_urdf",
    "joint_limits",
    "load_parameters",
    "model_hash",
    "q_index",
    "robot_model",
    "standing_configuration",
    "v_index",
]
assert sorted(__all__) == sorted(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
