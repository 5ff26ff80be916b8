"""rh5_msgs_py: the interface contract shared by all nodes of the RH5 control suite.

The names below are the contract's everyday vocabulary; the modules (``interfaces``, ``conversions``, ``realtime``,
``diagnostic_keys``, ...) hold the rest. Names resolve lazily (PEP 562,
:func:`rh5_msgs_py.lazy_exports.lazy_exports`): ``import rh5_msgs_py`` imports no other module of it, as every node
process imports it first."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .conversions import JointStateCodec, joint_state_from_msg, joint_state_to_msg
    from .names import (
        ACTUATOR_INDEX,
        ACTUATOR_NAMES,
        JOINT_INDEX,
        JOINT_NAMES,
        NUM_ACTUATORS,
        NUM_JOINTS,
        SUBMECHANISMS,
        Submechanism,
    )
    from .realtime import DeadlineLoop, LatencyWindow, LatestValue
    from .trajectory_file import TrajectoryData, TrajectoryFileError, load_trajectory, save_trajectory

_EXPORTS = {
    "ACTUATOR_INDEX": "names",
    "ACTUATOR_NAMES": "names",
    "JOINT_INDEX": "names",
    "JOINT_NAMES": "names",
    "NUM_ACTUATORS": "names",
    "NUM_JOINTS": "names",
    "SUBMECHANISMS": "names",
    "Submechanism": "names",
    "TrajectoryData": "trajectory_file",
    "TrajectoryFileError": "trajectory_file",
    "load_trajectory": "trajectory_file",
    "save_trajectory": "trajectory_file",
    "JointStateCodec": "conversions",
    "joint_state_from_msg": "conversions",
    "joint_state_to_msg": "conversions",
    "DeadlineLoop": "realtime",
    "LatencyWindow": "realtime",
    "LatestValue": "realtime",
}
__all__ = [
    "ACTUATOR_INDEX",
    "ACTUATOR_NAMES",
    "JOINT_INDEX",
    "JOINT_NAMES",
    "NUM_ACTUATORS",
    "NUM_JOINTS",
    "SUBMECHANISMS",
    "DeadlineLoop",
    "JointStateCodec",
    "LatencyWindow",
    "LatestValue",
    "Submechanism",
    "TrajectoryData",
    "TrajectoryFileError",
    "joint_state_from_msg",
    "joint_state_to_msg",
    "load_trajectory",
    "save_trajectory",
]

__getattr__ = lazy_exports(__name__, _EXPORTS)
