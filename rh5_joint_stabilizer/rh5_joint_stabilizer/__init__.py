"""rh5_joint_stabilizer: 1 kHz playback of planned trajectories and joint-space stabilisation, free of ROS here.

Names resolve lazily (PEP 562, :func:`rh5_msgs_py.lazy_exports.lazy_exports`): ``import rh5_joint_stabilizer``
imports none of its modules (the node, which needs rclpy, is ``rh5_joint_stabilizer.stabilizer_node``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .balance import AnkleBalanceCorrection
    from .controller import Command, Gains, Measurement, SafetyLimits, StabilizerCore, State, load_gains
    from .goal_check import GoalRejectedError, Tolerances
    from .reference import PlannedTrajectory, RampIn, ReferenceSample, TrajectoryRejectedError, validate_trajectory

_EXPORTS = {
    "Command": "controller",
    "Gains": "controller",
    "Measurement": "controller",
    "SafetyLimits": "controller",
    "StabilizerCore": "controller",
    "State": "controller",
    "load_gains": "controller",
    "PlannedTrajectory": "reference",
    "RampIn": "reference",
    "ReferenceSample": "reference",
    "TrajectoryRejectedError": "reference",
    "validate_trajectory": "reference",
    "AnkleBalanceCorrection": "balance",
    "GoalRejectedError": "goal_check",
    "Tolerances": "goal_check",
}
__all__ = [
    "AnkleBalanceCorrection",
    "Command",
    "Gains",
    "GoalRejectedError",
    "Measurement",
    "PlannedTrajectory",
    "RampIn",
    "ReferenceSample",
    "SafetyLimits",
    "StabilizerCore",
    "State",
    "Tolerances",
    "TrajectoryRejectedError",
    "load_gains",
    "validate_trajectory",
]

__getattr__ = lazy_exports(__name__, _EXPORTS)
