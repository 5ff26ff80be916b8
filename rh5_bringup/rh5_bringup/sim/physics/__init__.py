"""Whole-body physics of the simulated RH5, free of ROS: PyBullet's rigid bodies driven by the emulated boards.

* ``urdf``: the model as PyBullet loads it (contact spheres, armature, payloads);
* ``world``: `PhysicsWorld`, the robot on flat ground (contacts, readings, the crane, armature on the joints);
* ``coupling``: `PhysicsActuatorBank`, the boards' actuator bank on that world, and `build_physics`.

Names resolve lazily; every one of them imports PyBullet.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .coupling import (
        MAX_CATCH_UP_S,
        CouplingCounts,
        PhysicsActuatorBank,
        actuator_jacobian,
        build_physics,
        joint_dynamics,
        loaded_params,
    )
    from .urdf import CONTACT_RADIUS, contact_links, physics_urdf
    from .world import TIME_STEP, FootWrench, GroundTruth, JointDynamics, PhysicsWorld, Pose, quaternion_matrix

_EXPORTS = {
    **dict.fromkeys(
        (
            "MAX_CATCH_UP_S",
            "CouplingCounts",
            "PhysicsActuatorBank",
            "actuator_jacobian",
            "build_physics",
            "joint_dynamics",
            "loaded_params",
        ),
        "coupling",
    ),
    **dict.fromkeys(("CONTACT_RADIUS", "contact_links", "physics_urdf"), "urdf"),
    **dict.fromkeys(
        ("TIME_STEP", "FootWrench", "GroundTruth", "JointDynamics", "PhysicsWorld", "Pose", "quaternion_matrix"),
        "world",
    ),
}
__all__ = [
    "CONTACT_RADIUS",
    "MAX_CATCH_UP_S",
    "TIME_STEP",
    "CouplingCounts",
    "FootWrench",
    "GroundTruth",
    "JointDynamics",
    "PhysicsActuatorBank",
    "PhysicsWorld",
    "Pose",
    "actuator_jacobian",
    "build_physics",
    "contact_links",
    "joint_dynamics",
    "loaded_params",
    "physics_urdf",
    "quaternion_matrix",
]
__getattr__ = lazy_exports(__name__, _EXPORTS)
