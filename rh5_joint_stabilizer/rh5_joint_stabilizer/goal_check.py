"""FollowJointTrajectory goals as joint_trajectory_controller judges them, free of ROS: validation and tolerances.

``check_goal`` turns a goal into the trajectory the stabilizer plays and the tolerances it is held to, or raises
``GoalRejectedError`` with the result code and the reason. ``Tolerances`` follows control_msgs/JointTolerance:
per joint a position bound [rad]; in a goal, 0 keeps the server's default and -1 (any negative) lifts the check.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rh5_joint_stabilizer.reference import PlannedTrajectory, TrajectoryRejectedError, validate_trajectory
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.conversions import joint_trajectory_from_msg
from rh5_msgs_py.names import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

# control_msgs/action/FollowJointTrajectory result codes.
SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5


class GoalRejectedError(ValueError):
    """A goal the stabilizer does not take: ``code`` is the result code, the message the reason."""

    def __init__(self, code: int, reason: str) -> None:
        super().__init__(reason)
        self.code = code


@dataclass(frozen=True)
class Tolerances:
    """Position bounds per joint (JOINT_NAMES order, rad; 0 = not checked) and the time allowed after the end."""

    path: FloatArray
    goal: FloatArray
    goal_time_s: float

    @classmethod
    def uniform(cls, path: float, goal: float, goal_time_s: float) -> Tolerances:
        """The same bounds for every joint (the server's defaults)."""
        return cls(np.full(NUM_JOINTS, path), np.full(NUM_JOINTS, goal), goal_time_s)

    def with_goal(self, path: Sequence[Any], goal: Sequence[Any], goal_time_s: float) -> Tolerances:
        """These defaults overridden by a goal's JointTolerance lists and goal_time_tolerance (0: the default)."""
        return Tolerances(
            _override(self.path, path, "path_tolerance"),
            _override(self.goal, goal, "goal_tolerance"),
            goal_time_s if goal_time_s > 0.0 else self.goal_time_s,
        )


def _override(defaults: FloatArray, entries: Sequence[Any], what: str) -> FloatArray:
    out = defaults.copy()
    for entry in entries:
        if entry.name not in JOINT_INDEX:
            raise GoalRejectedError(INVALID_JOINTS, f"{what} names unknown joint {entry.name!r}")
        if not np.isfinite(entry.position):
            raise GoalRejectedError(INVALID_GOAL, f"{what} of {entry.name} is not finite")
        if entry.position > 0.0:
            out[JOINT_INDEX[entry.name]] = entry.position
        elif entry.position < 0.0:
            out[JOINT_INDEX[entry.name]] = 0.0  # -1: the check is lifted
    return out


def violations(error: FloatArray, bounds: FloatArray) -> str:
    """The joints whose |error| exceeds their (non-zero) bound, with both, or "" when none does."""
    over = np.flatnonzero((bounds > 0.0) & (np.abs(error) > bounds))
    worst = over[np.argsort(-np.abs(error[over]))]
    text = ", ".join(f"{JOINT_NAMES[j]} {error[j]:+.4g} rad (tolerance {bounds[j]:.4g})" for j in worst[:3])
    return text + (f" and {len(worst) - 3} more joints" if len(worst) > 3 else "")


def check_goal(
    goal: Any, now_ns: int, velocity_limits: FloatArray, defaults: Tolerances
) -> tuple[PlannedTrajectory, Tolerances]:
    """The trajectory and tolerances of a FollowJointTrajectory goal, or GoalRejectedError with code and reason.

    Like joint_trajectory_controller without partial goals: every joint of the robot, each once; at least one
    point; finite values; strictly increasing times; no step faster than a joint's velocity limit; a header stamp
    (0: now) such that the trajectory has not ended before it arrives; no multi-DOF part (RH5 has none).
    """
    trajectory = goal.trajectory
    if goal.multi_dof_trajectory.joint_names or goal.multi_dof_trajectory.points:
        raise GoalRejectedError(INVALID_JOINTS, "multi_dof_trajectory is not supported: RH5 has no multi-DOF joints")
    names = list(trajectory.joint_names)
    if unknown := [n for n in names if n not in JOINT_INDEX]:
        raise GoalRejectedError(INVALID_JOINTS, f"unknown joints {unknown}")
    if missing := [n for n in JOINT_NAMES if n not in names]:
        raise GoalRejectedError(INVALID_JOINTS, f"missing joints {missing} (partial goals are not accepted)")
    if not trajectory.points:
        raise GoalRejectedError(INVALID_GOAL, "the trajectory has no points")
    try:
        arrays = joint_trajectory_from_msg(trajectory)
    except ValueError as err:
        raise GoalRejectedError(INVALID_GOAL, str(err)) from None
    if arrays.positions is None:
        raise GoalRejectedError(INVALID_GOAL, "the points have no positions")
    stamp_ns = arrays.stamp_ns
    if stamp_ns > 0 and stamp_ns + int(arrays.times[-1] * 1e9) < now_ns:
        ago = (now_ns - stamp_ns) / 1e9 - arrays.times[-1]
        raise GoalRejectedError(OLD_HEADER_TIMESTAMP, f"the trajectory ended {ago:.3f} s before it arrived")
    try:
        planned = validate_trajectory(
            arrays.joint_names,
            arrays.times,
            arrays.positions,
            arrays.velocities,
            arrays.efforts,
            velocity_limits=velocity_limits,
        )
    except TrajectoryRejectedError as err:
        raise GoalRejectedError(INVALID_GOAL, str(err)) from None
    tolerance_s = goal.goal_time_tolerance.sec + 1e-9 * goal.goal_time_tolerance.nanosec
    return planned, defaults.with_goal(goal.path_tolerance, goal.goal_tolerance, tolerance_s)
