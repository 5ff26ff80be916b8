"""trajectory_msgs/MultiDOFJointTrajectory (the floating base) <-> numpy arrays."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from geometry_msgs.msg import Transform, Twist
from numpy.typing import ArrayLike
from trajectory_msgs.msg import (
    MultiDOFJointTrajectory,
    MultiDOFJointTrajectoryPoint,
)

from rh5_msgs_py.array_types import FloatArray

from ._common import NS_PER_S
from .joint_names import _listing, _unique_names
from .joint_trajectory import _checked_matrix, _point_times_ns, _timed_points, _trajectory
from .times import _check_increasing, _times_to_ns, time_to_ns


class BaseTrajectoryArrays(NamedTuple):
    """Floating-base trajectory as arrays: times (N,) s, positions (N,3) m, quaternions (N,4) xyzw,
    twists/accelerations (N,6) linear xyz then angular xyz (None if absent)."""

    times: FloatArray
    positions: FloatArray
    quaternions_xyzw: FloatArray
    twists: FloatArray | None
    accelerations: FloatArray | None
    joint_name: str = "floating_base"
    frame_id: str = "world"
    stamp_ns: int = 0


def _rows_as_lists(value: ArrayLike | None, shape: tuple[int, int], what: str) -> list[list[float]] | None:
    if value is None:
        return None
    return _checked_matrix(value, shape, what).tolist()  # type: ignore[no-any-return]


def _twist(values: list[float]) -> Twist:
    twist = Twist()
    lin, ang = twist.linear, twist.angular
    lin.x, lin.y, lin.z, ang.x, ang.y, ang.z = values
    return twist


def base_trajectory_to_msg(
    times_s: ArrayLike,
    positions: ArrayLike,
    quaternions_xyzw: ArrayLike,
    *,
    twists: ArrayLike | None = None,
    accelerations: ArrayLike | None = None,
    joint_name: str = "floating_base",
    frame_id: str = "world",
    stamp_ns: int = 0,
) -> MultiDOFJointTrajectory:
    """trajectory_msgs/MultiDOFJointTrajectory with one joint (the floating base) from arrays.

    Frames are passed through unchanged: the producer documents in which frame its twists are.
    """
    what = "MultiDOFJointTrajectory"
    ns = _times_to_ns(times_s, what)
    n_points = len(ns)
    pos = _rows_as_lists(positions, (n_points, 3), f"{what}.positions")
    quat = _rows_as_lists(quaternions_xyzw, (n_points, 4), f"{what}.quaternions_xyzw")
    vel = _rows_as_lists(twists, (n_points, 6), f"{what}.twists")
    acc = _rows_as_lists(accelerations, (n_points, 6), f"{what}.accelerations")
    assert pos is not None  # for the type checker
    assert quat is not None
    points = []
    for i, point in enumerate(_timed_points(MultiDOFJointTrajectoryPoint, ns)):
        transform = Transform()
        tr, rot = transform.translation, transform.rotation
        tr.x, tr.y, tr.z = pos[i]
        rot.x, rot.y, rot.z, rot.w = quat[i]
        point.transforms = [transform]
        if vel is not None:
            point.velocities = [_twist(vel[i])]
        if acc is not None:
            point.accelerations = [_twist(acc[i])]
        points.append(point)
    return _trajectory(MultiDOFJointTrajectory(), stamp_ns, frame_id, [joint_name], points)


def _twists_of(points: Sequence[MultiDOFJointTrajectoryPoint], attr: str, j: int, n: int) -> FloatArray | None:
    sizes = [len(getattr(p, attr)) for p in points]
    if not any(sizes):
        return None
    for i, size in enumerate(sizes):
        if size != n:
            msg = f"MultiDOFJointTrajectory: point {i} has {size} {attr} for {n} joints"
            raise ValueError(msg)
    return np.array(
        [
            (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z)
            for t in (getattr(p, attr)[j] for p in points)
        ],
        dtype=np.float64,
    ).reshape(len(points), 6)


def base_trajectory_from_msg(msg: MultiDOFJointTrajectory, joint_name: str | None = None) -> BaseTrajectoryArrays:
    """Arrays of one joint of a MultiDOFJointTrajectory (``joint_name``, or the only joint if None)."""
    what = "MultiDOFJointTrajectory"
    names = _unique_names(msg.joint_names, what)
    if joint_name is None:
        if len(names) != 1:
            text = f"{what}: has {len(names)} joints {_listing(names)}; say which one is the floating base"
            raise ValueError(text)
        j = 0
    elif joint_name in names:
        j = names.index(joint_name)
    else:
        text = f"{what}: no joint {joint_name!r} among {_listing(names)}"
        raise ValueError(text)
    points = msg.points
    ns = _point_times_ns(points)
    _check_increasing(ns, what)
    for i, p in enumerate(points):
        if len(p.transforms) != len(names):
            text = f"{what}: point {i} has {len(p.transforms)} transforms for {len(names)} joints"
            raise ValueError(text)
    transforms = [p.transforms[j] for p in points]
    positions = np.array(
        [(t.translation.x, t.translation.y, t.translation.z) for t in transforms], dtype=np.float64
    ).reshape(len(points), 3)
    quats = np.array(
        [(t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w) for t in transforms], dtype=np.float64
    ).reshape(len(points), 4)
    return BaseTrajectoryArrays(
        ns / NS_PER_S,
        positions,
        quats,
        _twists_of(points, "velocities", j, len(names)),
        _twists_of(points, "accelerations", j, len(names)),
        joint_name=names[j],
        frame_id=msg.header.frame_id,
        stamp_ns=time_to_ns(msg.header.stamp),
    )
