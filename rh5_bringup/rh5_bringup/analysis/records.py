"""What the report reads from a bag: one typed record per topic of the suite, in seconds since the first message."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rh5_msgs_py.array_types import FloatArray


class ReportError(Exception):
    """The report cannot be made (bad arguments or input)."""


class NotABagError(ReportError):
    """The path is not a readable rosbag2 folder."""


@dataclass(frozen=True)
class JointSeries:
    """A JointState stream: times (n,) s, and (n, len(names)) arrays, NaN where a message had no value."""

    topic: str
    names: tuple[str, ...]
    t: FloatArray
    position: FloatArray
    velocity: FloatArray
    effort: FloatArray
    time_source: str
    wall_t: FloatArray | None = None
    """The times on the wall clock the loops ran on where ``t`` is simulated time, else None."""
    publish_ns: NDArray[np.int64] | None = field(default=None, repr=False)
    """When the sender's middleware published each message (the bag's publish times: wall clock), if known."""

    def index(self, name: str) -> int | None:
        """Column of ``name`` (None if the stream never carried it)."""
        return self.names.index(name) if name in self.names else None


@dataclass(frozen=True)
class PoseSeries:
    """geometry_msgs/PoseStamped stream: times (n,) s, positions (n, 3) m, quaternions (n, 4) xyzw."""

    topic: str
    t: FloatArray
    position: FloatArray
    quaternion_xyzw: FloatArray
    time_source: str
    wall_t: FloatArray | None = None
    """As JointSeries.wall_t."""
    publish_ns: NDArray[np.int64] | None = field(default=None, repr=False)
    """As JointSeries.publish_ns."""


@dataclass(frozen=True)
class WrenchSeries:
    """geometry_msgs/WrenchStamped stream: times (n,) s, force (n, 3) N, torque (n, 3) Nm."""

    topic: str
    t: FloatArray
    force: FloatArray
    torque: FloatArray
    time_source: str


@dataclass(frozen=True)
class BoolSeries:
    """std_msgs/Bool stream (receive times)."""

    topic: str
    t: FloatArray
    value: NDArray[np.bool_]


@dataclass(frozen=True)
class PlannedJoints:
    """One planned_trajectory message: received at ``t`` (s); knot times (N,) s from its start."""

    t: float
    names: tuple[str, ...]
    times: FloatArray
    positions: FloatArray
    velocities: FloatArray | None


@dataclass(frozen=True)
class PlannedBase:
    """One planned_base_trajectory message: knot times (N,) s, positions (N, 3) m, quaternions (N, 4) xyzw."""

    t: float
    times: FloatArray
    positions: FloatArray
    quaternion_xyzw: FloatArray


@dataclass(frozen=True)
class DiagnosticRecord:
    """One DiagnosticStatus as published: time (s), name, level (0 OK .. 3 STALE), message, key/values."""

    t: float
    name: str
    level: int
    message: str
    values: dict[str, str]


@dataclass
class Recording:
    """Everything of a bag the report uses; None / empty where a topic was not recorded."""

    path: Path
    origin_ns: int
    duration_s: float
    topic_counts: dict[str, int]
    joint_commands: JointSeries | None = None
    joint_states: JointSeries | None = None
    actuator_commands: JointSeries | None = None
    actuator_states: JointSeries | None = None
    base_pose: PoseSeries | None = None
    wrench_left: WrenchSeries | None = None
    wrench_right: WrenchSeries | None = None
    estopped: BoolSeries | None = None
    planned_joints: list[PlannedJoints] = field(default_factory=list)
    planned_base: list[PlannedBase] = field(default_factory=list)
    diagnostics: list[DiagnosticRecord] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    sim_speed: float | None = None
    """Simulated seconds per wall-clock second over the recording (/clock), None without a simulation clock."""


__all__ = [
    "BoolSeries",
    "DiagnosticRecord",
    "JointSeries",
    "NotABagError",
    "PlannedBase",
    "PlannedJoints",
    "PoseSeries",
    "Recording",
    "ReportError",
    "WrenchSeries",
]
