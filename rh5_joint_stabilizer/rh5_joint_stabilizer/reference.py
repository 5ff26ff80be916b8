"""Reference trajectories the stabilizer plays: validated planned motions and the ramp-in move.

A planned trajectory is checked once, when it arrives (names, finiteness, strictly
increasing times, no jump faster than the joint velocity limits), and is then sampled
every millisecond with cubic Hermite splines through the knots' positions and velocities
(torques linearly), so the 1 kHz loop never meets bad data.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.hermite import hermite_weights
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS

JUMP_MARGIN = 1.05  # a knot-to-knot move may reach 105 % of the velocity limit (rounding of planned knots)


class TrajectoryRejectedError(ValueError):
    """A trajectory the stabilizer refuses to play; the message says why."""


class ReferenceSample(NamedTuple):
    """Reference position, velocity and feed-forward torque for one instant (joint order)."""

    position: FloatArray
    velocity: FloatArray
    effort: FloatArray


@dataclass(frozen=True)
class PlannedTrajectory:
    """A validated joint trajectory (JOINT_NAMES order) sampled with cubic Hermite splines."""

    times: FloatArray  # (N,) seconds from the start, strictly increasing, times[0] == 0
    positions: FloatArray  # (N, 32)
    velocities: FloatArray  # (N, 32)
    efforts: FloatArray  # (N, 32)
    _segments: FloatArray = field(init=False, repr=False, compare=False)
    """(N-1, 4, 32): each segment's p0, h v0, p1, h v1, so that a sample is two 4-vector products (1 kHz)."""

    def __post_init__(self) -> None:
        h = np.diff(self.times)[:, None]
        p, v = self.positions, self.velocities
        segments = np.stack([p[:-1], v[:-1] * h, p[1:], v[1:] * h], axis=1) if len(p) > 1 else np.zeros((0, 4, 0))
        object.__setattr__(self, "_segments", segments)

    @property
    def duration(self) -> float:
        """Time of the last knot [s]."""
        return float(self.times[-1])

    def sample(self, t: float) -> ReferenceSample:
        """The reference at time ``t``: clamped to the first/last knot outside [0, duration]."""
        times = self.times
        if t <= 0.0 or len(times) == 1:
            return ReferenceSample(self.positions[0], np.zeros(NUM_JOINTS), self.efforts[0])
        if t >= times[-1]:
            return ReferenceSample(self.positions[-1], np.zeros(NUM_JOINTS), self.efforts[-1])
        k = int(np.searchsorted(times, t, side="right")) - 1
        h = times[k + 1] - times[k]
        s = float((t - times[k]) / h)
        segment = self._segments[k]
        weights, slopes = hermite_weights(s)
        position = weights @ segment
        velocity = slopes @ segment / h
        effort = (1 - s) * self.efforts[k] + s * self.efforts[k + 1]
        return ReferenceSample(position, velocity, effort)


def validate_trajectory(
    names: tuple[str, ...] | list[str],
    times: FloatArray,
    positions: FloatArray,
    velocities: FloatArray | None,
    efforts: FloatArray | None,
    *,
    velocity_limits: FloatArray,
) -> PlannedTrajectory:
    """Check a trajectory and reorder it to JOINT_NAMES; raise TrajectoryRejectedError with the reason."""
    unknown = [n for n in names if n not in JOINT_NAMES]
    if unknown:
        msg = f"unknown joints {unknown}"
        raise TrajectoryRejectedError(msg)
    missing = [n for n in JOINT_NAMES if n not in names]
    if missing:
        msg = f"missing joints {missing}"
        raise TrajectoryRejectedError(msg)
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or len(times) == 0:
        msg = "no trajectory points"
        raise TrajectoryRejectedError(msg)
    order = np.array([list(names).index(n) for n in JOINT_NAMES])
    fields = []
    for label, values in (("positions", positions), ("velocities", velocities), ("efforts", efforts)):
        if values is None:
            fields.append(np.zeros((len(times), NUM_JOINTS)))
            continue
        array = np.asarray(values, dtype=np.float64)
        if array.shape != (len(times), len(names)):
            msg = f"{label} have shape {array.shape}, expected {(len(times), len(names))}"
            raise TrajectoryRejectedError(msg)
        if not np.isfinite(array).all():
            row = int(np.argwhere(~np.isfinite(array))[0][0])
            msg = f"NaN or inf in {label} at point {row}"
            raise TrajectoryRejectedError(msg)
        fields.append(array[:, order])
    if not np.isfinite(times).all():
        msg = "NaN or inf in the time stamps"
        raise TrajectoryRejectedError(msg)
    steps = np.diff(times)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0))
        msg = f"time stamps not strictly increasing at point {k + 1} ({times[k]:.6f} s then {times[k + 1]:.6f} s)"
        raise TrajectoryRejectedError(msg)
    position = fields[0]
    if len(times) > 1:
        speed = np.abs(np.diff(position, axis=0)) / steps[:, None]
        excess = speed / velocity_limits
        if (excess > JUMP_MARGIN).any():
            k, j = np.unravel_index(int(np.argmax(excess)), excess.shape)
            msg = (
                f"jump of {JOINT_NAMES[j]} between points {k} and {k + 1}: {speed[k, j]:.3f} rad/s "
                f"exceeds its velocity limit {velocity_limits[j]:.3f} rad/s"
            )
            raise TrajectoryRejectedError(msg)
    return PlannedTrajectory(times - times[0], position, fields[1], fields[2])


@dataclass(frozen=True)
class RampIn:
    """A straight joint-space move from ``start`` to ``goal`` with a trapezoidal speed profile.

    All joints move along the same normalised profile, so the joint with the longest way
    sets the duration and every joint stays within ``max_velocity`` and ``max_acceleration``.
    """

    start: FloatArray
    goal: FloatArray
    max_velocity: float
    max_acceleration: float

    @property
    def distance(self) -> float:
        """Largest joint displacement [rad]."""
        return float(np.max(np.abs(self.goal - self.start), initial=0.0))

    @property
    def duration(self) -> float:
        """Shortest duration of the limited profile over the largest displacement [s]."""
        d, v, a = self.distance, self.max_velocity, self.max_acceleration
        if d == 0.0:
            return 0.0
        if d <= v * v / a:  # never reaches full speed: triangle profile
            return 2.0 * math.sqrt(d / a)
        return d / v + v / a

    def sample(self, t: float) -> ReferenceSample:
        """Reference at ``t`` seconds into the ramp (holds the goal afterwards)."""
        d, total = self.distance, self.duration
        if d == 0.0 or t >= total:
            return ReferenceSample(self.goal, np.zeros_like(self.goal), np.zeros_like(self.goal))
        t = max(t, 0.0)
        a = self.max_acceleration
        v_peak = min(self.max_velocity, math.sqrt(d * a))
        t_acc = v_peak / a
        if t < t_acc:
            s, sd = 0.5 * a * t * t, a * t
        elif t < total - t_acc:
            s, sd = 0.5 * a * t_acc * t_acc + v_peak * (t - t_acc), v_peak
        else:
            rest = total - t
            s, sd = d - 0.5 * a * rest * rest, a * rest
        direction = (self.goal - self.start) / d
        return ReferenceSample(self.start + s * direction, sd * direction, np.zeros_like(self.goal))
