"""When trajectory time 0 was in the bag: the moment the stabilizer started playing the plan.

The stabilizer reports its state on /diagnostics once a second, which brackets the start of
playback to a 1 s window. Within it (or, without diagnostics, among the joint_commands samples
that equal the first planned sample: the ramp-in ends exactly there) the start is the time shift
that best lines joint_commands up with planned_trajectory, to the 1 ms of the command stream.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from rh5_bringup.analysis.metrics import Transition, interpolate_clamped, resample
from rh5_bringup.analysis.records import JointSeries, PlannedJoints
from rh5_msgs_py.array_types import FloatArray

FIT_HORIZON_S: Final = 10.0
"""Seconds of the plan compared when aligning (enough to include motion, bounded cost)."""
FIT_SAMPLES: Final = 200
COARSE_CANDIDATES: Final = 100
START_TOLERANCE_RAD: Final = 1e-3
"""A command equals the first planned sample when the median |difference| over joints is below this."""
MAX_FIT_RESIDUAL_RAD: Final = 0.02
"""A best fit worse than this (mean |command - plan|) means the commands do not follow this plan."""
TIE_RAD: Final = 1e-6


@dataclass(frozen=True)
class TimeZero:
    """Trajectory time 0 in bag seconds (None if unknown), how it was found, and the fit residual (rad)."""

    t0: float | None
    method: str
    residual: float | None = None
    episodes: int = 0


def playing_window(transitions: Sequence[Transition], reports: Sequence[float]) -> tuple[float, float] | None:
    """(last report before, first report in) the first ``playing`` state, in bag seconds."""
    first = next((tr for tr in transitions if tr.state == "playing"), None)
    if first is None:
        return None
    before = [t for t in reports if t < first.t]
    return (before[-1] if before else first.t - 1.0, first.t)


class _Fit:
    """Mean |joint_commands - plan| over the plan's first seconds for candidate start times."""

    def __init__(self, commands: JointSeries, planned: PlannedJoints) -> None:
        names = [n for n in planned.names if n in commands.names]
        self.cmd_t = commands.t
        self.cmd = commands.position[:, [commands.names.index(n) for n in names]]
        horizon = min(float(planned.times[-1]), FIT_HORIZON_S)
        self.tau = np.linspace(0.0, horizon, FIT_SAMPLES)
        plan = planned.positions[:, [planned.names.index(n) for n in names]]
        self.plan = interpolate_clamped(planned.times, plan, self.tau)
        self.first = plan[0]

    def cost(self, starts: FloatArray) -> FloatArray:
        times = (starts[:, None] + self.tau[None, :]).ravel()
        values, valid = resample(self.cmd_t, self.cmd, times)
        diff = np.abs(values - np.tile(self.plan, (len(starts), 1))).mean(axis=1)
        diff = np.where(valid, diff, np.nan).reshape(len(starts), len(self.tau))
        counts = np.isfinite(diff).sum(axis=1)
        total = np.nansum(diff, axis=1)
        # a start whose comparison runs past the recorded commands counts only where commands exist,
        # but needs at least a quarter of the samples to be judged
        return np.where(counts >= len(self.tau) // 4, total / np.maximum(counts, 1), np.inf)

    def at_first_sample(self) -> FloatArray:
        """Command times whose value equals the first planned sample."""
        near = np.median(np.abs(self.cmd - self.first), axis=1) < START_TOLERANCE_RAD
        return self.cmd_t[near]

    def best(self, candidates: FloatArray) -> tuple[float, float] | None:
        """(start, residual) minimising the cost; ties go to the earliest candidate."""
        if not len(candidates):
            return None
        step = max(1, len(candidates) // COARSE_CANDIDATES)
        coarse = np.arange(0, len(candidates), step)
        costs = self.cost(candidates[coarse])
        if not np.isfinite(costs).any():
            return None
        i = int(coarse[int(np.argmin(costs))])
        fine = np.arange(max(0, i - 2 * step), min(len(candidates), i + 2 * step + 1))
        costs = self.cost(candidates[fine])
        best = float(np.min(costs))
        j = int(fine[int(np.flatnonzero(costs <= best + TIE_RAD)[0])])
        return float(candidates[j]), best


def trajectory_time_zero(
    transitions: Sequence[Transition],
    reports: Sequence[float],
    commands: JointSeries | None,
    planned: PlannedJoints | None,
) -> TimeZero:
    """Find trajectory time 0; ``reports`` are the times of the stabilizer's diagnostics reports."""
    episodes = sum(tr.state == "playing" for tr in transitions)
    window = playing_window(transitions, reports)
    fit = _Fit(commands, planned) if commands is not None and planned is not None and len(planned.times) else None
    if window is not None:
        lo, hi = window
        coarse = f"stabilizer diagnostics: playing from between {lo:.3f} s and {hi:.3f} s"
        if fit is not None:
            candidates = fit.cmd_t[(fit.cmd_t >= lo - 0.05) & (fit.cmd_t <= hi + 0.05)]
            found = fit.best(candidates)
            if found is not None and found[1] <= MAX_FIT_RESIDUAL_RAD:
                method = f"{coarse}, refined by aligning joint_commands with planned_trajectory"
                return TimeZero(found[0], method, found[1], episodes)
            why = "joint_commands do not follow planned_trajectory there"
            return TimeZero(hi, f"{coarse}; taken as {hi:.3f} s ({why}): accurate to ~1 s", None, episodes)
        return TimeZero(hi, f"{coarse}; taken as {hi:.3f} s (no joint_commands/plan to refine): accurate to ~1 s")
    if fit is None:
        missing = [n for n, v in (("joint_commands", commands), ("planned_trajectory", planned)) if v is None]
        why = f"no stabilizer diagnostics in playing state and no {' / '.join(missing) or 'usable plan'}"
        return TimeZero(None, f"unknown: {why}")
    found = fit.best(fit.at_first_sample())
    if found is None or found[1] > MAX_FIT_RESIDUAL_RAD:
        return TimeZero(None, "unknown: no stabilizer diagnostics, and joint_commands never follow planned_trajectory")
    method = (
        "no stabilizer diagnostics in playing state: the joint_commands sample equal to the first planned sample "
        "from which the commands best follow planned_trajectory (the ramp-in ends at that sample)"
    )
    return TimeZero(found[0], method, found[1], episodes)
