"""The messages the planner node publishes for a trajectory: joints, floating base and planned foot wrenches.

:func:`planned_messages` samples a :class:`~rh5_msgs_py.trajectory_file.TrajectoryData` at ``rate_hz`` with
:func:`rh5_planner.interpolation.interpolate` and converts it:

* ``planned_trajectory`` (trajectory_msgs/JointTrajectory, JOINT_NAMES): positions and velocities of the
  cubic Hermite splines, accelerations (their second derivative) and efforts (the planned torques, held over
  each knot interval as the Euler integrator applied them).
* ``planned_base_trajectory`` (trajectory_msgs/MultiDOFJointTrajectory, one joint ``floating_base`` in frame
  ``world``): base position and orientation; the twists are those of the trajectory file, i.e. expressed in
  the base frame (pinocchio LOCAL), linear then angular.
* ``planned_wrench/left_foot`` and ``right_foot`` (geometry_msgs/WrenchStamped): the planned contact wrench
  of the FIRST sample only (force then torque on the sole, in the sole frame ``LLFoot_Sole``/``LRFoot_Sole``,
  about its origin), stamped like the trajectories. The full wrench series stays in the trajectory file;
  the topics are volatile (EVENT_QOS), so only subscribers present at publish time get them.

Every message of one publication carries the same header stamp. The sample times are made unique at
nanosecond resolution: ``interpolate`` adds every knot time to the grid, and a knot such as 0.09 s lies
1e-17 s away from the grid's 0.09000000000000001 s, which JointTrajectory cannot tell apart.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.conversions import base_trajectory_to_msg, joint_trajectory_to_msg, wrench_to_msg
from rh5_msgs_py.names import FOOT_FRAMES, JOINT_NAMES
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData

from .interpolation import interpolate

__all__ = ["BASE_FRAME", "BASE_JOINT", "PlannedMessages", "hold_messages", "planned_messages"]

BASE_JOINT: Final = "floating_base"
BASE_FRAME: Final = "world"


@dataclass(frozen=True, eq=False)
class PlannedMessages:
    """One publication: the joint and base trajectories and, if known, the planned wrench per foot."""

    joint: Any
    base: Any
    wrenches: dict[str, Any]
    samples: int
    duration_s: float


def _distinct_ns(times: FloatArray) -> npt.NDArray[np.intp]:
    """Indices of the first sample of every distinct nanosecond time (times ascending)."""
    ns = np.rint(times * 1e9).astype(np.int64)
    return np.flatnonzero(np.concatenate([[True], np.diff(ns) > 0]))


def planned_messages(data: TrajectoryData, rate_hz: float, stamp_ns: int) -> PlannedMessages:
    """The messages of ``data`` sampled at ``rate_hz`` (see the module docstring), stamped ``stamp_ns``."""
    sampled = interpolate(data, rate_hz)
    keep = _distinct_ns(sampled.times)
    times = sampled.times[keep] - sampled.times[0]
    states = sampled.states[keep]
    joint = joint_trajectory_to_msg(
        JOINT_NAMES,
        times,
        states[:, 7:NQ],
        velocities=states[:, NQ + 6 :],
        accelerations=sampled.joint_accelerations[keep],
        efforts=sampled.controls[keep],
        stamp_ns=stamp_ns,
    )
    base = base_trajectory_to_msg(
        times,
        states[:, :3],
        states[:, 3:7],
        twists=states[:, NQ : NQ + 6],
        joint_name=BASE_JOINT,
        frame_id=BASE_FRAME,
        stamp_ns=stamp_ns,
    )
    first = data.contact_wrenches[0]
    wrenches = {side: wrench_to_msg(first[k], FOOT_FRAMES[side], stamp_ns) for k, side in enumerate(("left", "right"))}
    return PlannedMessages(joint, base, wrenches, samples=len(times), duration_s=float(times[-1]))


def hold_messages(
    joint_positions: FloatArray, base_pose_xyz_xyzw: FloatArray, duration_s: float, stamp_ns: int
) -> PlannedMessages:
    """A two-sample hold of one pose (joints in JOINT_NAMES order, base xyz + quaternion xyzw), at rest."""
    times = np.array([0.0, duration_s])
    q = np.vstack([joint_positions, joint_positions])
    zeros = np.zeros_like(q)
    joint = joint_trajectory_to_msg(JOINT_NAMES, times, q, velocities=zeros, stamp_ns=stamp_ns)
    pose = np.vstack([base_pose_xyz_xyzw, base_pose_xyz_xyzw])
    base = base_trajectory_to_msg(
        times,
        pose[:, :3],
        pose[:, 3:7],
        twists=np.zeros((2, 6)),
        joint_name=BASE_JOINT,
        frame_id=BASE_FRAME,
        stamp_ns=stamp_ns,
    )
    return PlannedMessages(joint, base, {}, samples=2, duration_s=duration_s)
