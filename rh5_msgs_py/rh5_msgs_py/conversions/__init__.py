"""Vectorised conversions between numpy arrays and the common_interfaces messages of the suite.

Float64 array fields are filled from ``array.array('d', ndarray.tobytes())`` (a memcpy, ~0.4 us for 32
values) and read with ``np.frombuffer`` (zero copy). Assigning an ndarray to a rosidl field iterates it
element by element (~2.5 us) and fails the field check when ROS_PYTHON_CHECK_FIELDS=1. For 1 kHz paths,
:class:`JointStateCodec` reuses one message and writes into its arrays in place (bench/msgs_roundtrip.py).
Values are converted, not judged: NaN passes through; shapes, names and times are checked.

One module per message family (times, joint_names, joint_state, joint_trajectory, base_trajectory, wrench,
diagnostics); this package re-exports their public names.
"""

from __future__ import annotations

from .base_trajectory import BaseTrajectoryArrays, base_trajectory_from_msg, base_trajectory_to_msg
from .diagnostics import Level, Status, diagnostics_from_msg, diagnostics_to_msg, status_from_msg, status_to_msg
from .joint_names import JointNameIndex
from .joint_state import JointStateArrays, JointStateCodec, joint_state_from_msg, joint_state_to_msg
from .joint_trajectory import (
    JointTrajectoryArrays,
    joint_trajectory_from_cdr,
    joint_trajectory_from_msg,
    joint_trajectory_to_msg,
)
from .times import duration_to_ns, duration_to_s, seconds_to_ns, time_to_ns, time_to_s, to_duration_msg, to_time_msg
from .wrench import wrench_from_msg, wrench_to_msg

__all__ = [
    "BaseTrajectoryArrays",
    "JointNameIndex",
    "JointStateArrays",
    "JointStateCodec",
    "JointTrajectoryArrays",
    "Level",
    "Status",
    "base_trajectory_from_msg",
    "base_trajectory_to_msg",
    "diagnostics_from_msg",
    "diagnostics_to_msg",
    "duration_to_ns",
    "duration_to_s",
    "joint_state_from_msg",
    "joint_state_to_msg",
    "joint_trajectory_from_cdr",
    "joint_trajectory_from_msg",
    "joint_trajectory_to_msg",
    "seconds_to_ns",
    "status_from_msg",
    "status_to_msg",
    "time_to_ns",
    "time_to_s",
    "to_duration_msg",
    "to_time_msg",
    "wrench_from_msg",
    "wrench_to_msg",
]
