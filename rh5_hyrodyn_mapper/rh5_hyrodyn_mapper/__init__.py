"""rh5_hyrodyn_mapper: the RH5 model's joint <-> actuator maps (one C kernel per mechanism), the mapper's safety
rules and the link tree behind /tf.

Names resolve lazily (PEP 562, :func:`rh5_msgs_py.lazy_exports.lazy_exports`): ``import rh5_hyrodyn_mapper`` imports
none of its modules, so a node that needs one map does not pay for the model, pinocchio or the kinematics until it
uses them."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

from .openmp_default import default_openmp_to_one_thread

default_openmp_to_one_thread()  # before anything here imports Pinocchio

if TYPE_CHECKING:
    from .kinematics import (
        ForwardKinematicsError,
        KinematicsError,
        SingularityError,
        SubmechanismModel,
        build_submechanisms,
        submechanism_models,
    )
    from .mapper_core import MapperCore
    from .mapping import (
        DEFAULT_MAX_CONDITION,
        ActuatorSample,
        JointSample,
        LimitReport,
        RobotMapper,
        Violation,
        robot_mapper,
    )
    from .tf_tree import KinematicTree

_EXPORTS = {
    "DEFAULT_MAX_CONDITION": "mapping",
    "ActuatorSample": "mapping",
    "JointSample": "mapping",
    "LimitReport": "mapping",
    "RobotMapper": "mapping",
    "Violation": "mapping",
    "robot_mapper": "mapping",
    "ForwardKinematicsError": "kinematics",
    "KinematicsError": "kinematics",
    "SingularityError": "kinematics",
    "SubmechanismModel": "kinematics",
    "build_submechanisms": "kinematics",
    "submechanism_models": "kinematics",
    "MapperCore": "mapper_core",
    "KinematicTree": "tf_tree",
}
__all__ = [
    "DEFAULT_MAX_CONDITION",
    "ActuatorSample",
    "ForwardKinematicsError",
    "JointSample",
    "KinematicTree",
    "KinematicsError",
    "LimitReport",
    "MapperCore",
    "RobotMapper",
    "SingularityError",
    "SubmechanismModel",
    "Violation",
    "build_submechanisms",
    "robot_mapper",
    "submechanism_models",
]

__getattr__ = lazy_exports(__name__, _EXPORTS)
