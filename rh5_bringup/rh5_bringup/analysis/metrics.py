"""The numbers of an experiment report: tracking errors, floating-base deviation, falls, timing, faults.

Pure functions of the arrays of rh5_bringup.analysis.load; every one is vectorised over samples and joints.
Errors are measured minus reference (a measured value 1 mrad above its reference is +1 mrad).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import NDArray

from rh5_bringup.analysis.records import BoolSeries, DiagnosticRecord, JointSeries, PlannedBase, PoseSeries
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.diagnostic_keys import (
    PHYSICS_TASK,
    ControlKeys,
    DriverKeys,
    LoopKeys,
    MapperKeys,
    StabilizerKeys,
    task_name,
    task_prefix,
)
from rh5_msgs_py.interfaces import SIM_HARDWARE_NODE, STABILIZER_NODE
from rh5_msgs_py.names import JOINT_GROUPS, LINEAR_ACTUATOR_NAMES, SUBMECHANISMS
from rh5_msgs_py.realtime import jitter_above_us, jitter_percentile_us, parse_jitter_histogram

MAX_GAP_S: Final = 0.05
"""A reference is interpolated only between samples at most this far apart (else the sample is left out)."""
BASE_BAND_M: Final[dict[str, tuple[float, float]]] = {"x": (-0.010, 0.010), "y": (-0.010, 0.010), "z": (-0.005, 0.005)}
"""The paper's PyBullet result for the planned walk under joint-space PD (Sec. Simulation Results,
fig:walkDynamic_pybullet): the floating base deviates about +-10 mm in x and y and +5 mm in z. The paper
reports only the upward z excursion; a sinking base is at least as bad, so z is checked as +-5 mm."""
FALL_HEIGHT_FRACTION: Final = 0.6
"""The robot fell if its base is below this fraction of the planned (else the initial) base height."""
FALL_TILT_DEG: Final = 45.0
"""... or its base z axis is tilted more than this from the vertical."""
BENIGN_REASONS: Final = ("trajectory finished", "requested", "ramp-in")
"""Stabilizer transitions that are the normal course of an experiment, not faults."""

ACTUATOR_GROUPS: Final[dict[str, tuple[str, ...]]] = {
    group: tuple(
        a for s in SUBMECHANISMS if set(s.joints) <= set(joints) for a in s.actuators if a in LINEAR_ACTUATOR_NAMES
    )
    for group, joints in JOINT_GROUPS.items()
}
"""The linear actuators (m) of each joint group; rotary actuators are their joints and appear in joint space."""


# --- resampling --------------------------------------------------------------------------------------------------


def resample(
    t: FloatArray, values: FloatArray, at: FloatArray, max_gap: float = MAX_GAP_S
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Linear interpolation of ``values`` (n, k) sampled at sorted ``t`` (n,) at times ``at`` (m,).

    Returns (m, k) values and an (m,) validity mask: inside [t[0], t[-1]] and between samples at most
    ``max_gap`` apart (a gap means the publisher was silent, e.g. the stabilizer idle).
    """
    at = np.asarray(at, dtype=np.float64)
    if len(t) == 0:
        return np.full((len(at), values.shape[1]), np.nan), np.zeros(len(at), dtype=bool)
    if len(t) == 1:
        valid = np.abs(at - t[0]) <= max_gap / 2
        return np.repeat(values[:1], len(at), axis=0), valid
    hi = np.clip(np.searchsorted(t, at, side="right"), 1, len(t) - 1)
    lo = hi - 1
    dt = t[hi] - t[lo]
    w = np.divide(at - t[lo], dt, out=np.zeros_like(at), where=dt > 0)
    w = np.clip(w, 0.0, 1.0)[:, None]
    out = values[lo] * (1.0 - w) + values[hi] * w
    valid = (at >= t[0]) & (at <= t[-1]) & (dt <= max_gap)
    return out, valid


def interpolate_clamped(times: FloatArray, values: FloatArray, at: FloatArray) -> FloatArray:
    """Knot values (N, k) at times ``at``, held at the first / last knot outside the knot range."""
    at = np.clip(np.asarray(at, dtype=np.float64), times[0], times[-1])
    out, _ = resample(times, values, at, max_gap=np.inf)
    return out


# --- tracking ----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Tracking:
    """Reference and measurement of one space at the measurement times within the evaluation window."""

    names: tuple[str, ...]
    t: FloatArray
    reference: FloatArray
    measured: FloatArray
    window: tuple[float, float]

    @property
    def error(self) -> FloatArray:
        """Measured minus reference, (n, k)."""
        return self.measured - self.reference

    @property
    def rms(self) -> FloatArray:
        """Per-name RMS error over the window (NaN for a name never measured)."""
        return _nan_rms(self.error, axis=0)

    @property
    def max_abs(self) -> FloatArray:
        """Per-name largest |error| over the window."""
        return _nan_max_abs(self.error, axis=0)

    def column(self, name: str) -> int:
        """Index of ``name`` (KeyError if this space has no such name)."""
        return self.names.index(name)


def _nan_rms(x: FloatArray, axis: int | None = None) -> FloatArray:
    finite = np.isfinite(x)
    count = finite.sum(axis=axis)
    total = np.where(finite, x * x, 0.0).sum(axis=axis)
    return np.sqrt(np.divide(total, count, out=np.full_like(total, np.nan, dtype=np.float64), where=count > 0))


def _nan_max_abs(x: FloatArray, axis: int | None = None) -> FloatArray:
    finite = np.isfinite(x)
    out = np.where(finite, np.abs(x), -np.inf).max(axis=axis, initial=-np.inf)
    return np.where(np.isfinite(out), out, np.nan)


def tracking(
    reference: JointSeries, measured: JointSeries, window: tuple[float, float] | None = None
) -> Tracking | None:
    """Reference interpolated at the measurement times, for the names both carry (None if nothing overlaps).

    ``window`` (bag seconds) limits the samples, e.g. to the played trajectory.
    """
    names = tuple(n for n in reference.names if n in measured.names)
    if not names or len(reference.t) == 0 or len(measured.t) == 0:
        return None
    ref_cols = [reference.names.index(n) for n in names]
    mea_cols = [measured.names.index(n) for n in names]
    lo, hi = window if window is not None else (-np.inf, np.inf)
    inside = (measured.t >= lo) & (measured.t <= hi)
    at = measured.t[inside]
    values, valid = resample(reference.t, reference.position[:, ref_cols], at)
    if not valid.any():
        return None
    t = at[valid]
    span = (float(t[0]), float(t[-1])) if window is None else window
    return Tracking(names, t, values[valid], measured.position[inside][valid][:, mea_cols], span)


@dataclass(frozen=True)
class GroupError:
    """RMS and max |error| over the names of one group, and the name with the largest RMS."""

    group: str
    names: tuple[str, ...]
    rms: float
    max_abs: float
    worst: str


def group_errors(result: Tracking, groups: Mapping[str, Sequence[str]]) -> list[GroupError]:
    """One GroupError per group that has at least one name in ``result``."""
    out = []
    rms = result.rms
    for group, members in groups.items():
        cols = [result.names.index(n) for n in members if n in result.names]
        if not cols:
            continue
        err = result.error[:, cols]
        worst = cols[int(np.nanargmax(np.nan_to_num(rms[cols], nan=-1.0)))]
        out.append(
            GroupError(
                group,
                tuple(result.names[c] for c in cols),
                float(_nan_rms(err)),
                float(_nan_max_abs(err)),
                result.names[worst],
            )
        )
    return out


# --- floating base -----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BaseDeviation:
    """Measured minus planned base position at the same trajectory time ``tau`` (s), in m."""

    tau: FloatArray
    deviation: FloatArray
    motion_end: float

    def _during(self) -> FloatArray:
        return self.deviation[(self.tau >= 0.0) & (self.tau <= self.motion_end)]

    @property
    def rms(self) -> FloatArray:
        """Per-axis RMS deviation during the motion (m)."""
        return _nan_rms(self._during(), axis=0)

    @property
    def minimum(self) -> FloatArray:
        """Per-axis smallest deviation during the motion (m)."""
        d = self._during()
        return d.min(axis=0) if len(d) else np.full(3, np.nan)

    @property
    def maximum(self) -> FloatArray:
        """Per-axis largest deviation during the motion (m)."""
        d = self._during()
        return d.max(axis=0) if len(d) else np.full(3, np.nan)

    @property
    def at_start(self) -> FloatArray:
        """Deviation at trajectory time 0 (the offset between the simulated and the planned start)."""
        if not len(self.tau):
            return np.full(3, np.nan)
        return self.deviation[int(np.argmin(np.abs(self.tau)))]

    def within_band(self, band: Mapping[str, tuple[float, float]] = BASE_BAND_M) -> dict[str, bool]:
        """Per axis: did the deviation stay inside ``band`` during the motion?"""
        lo, hi = self.minimum, self.maximum
        return {ax: bool(lo[i] >= band[ax][0] and hi[i] <= band[ax][1]) for i, ax in enumerate("xyz")}


def base_deviation(pose: PoseSeries, planned: PlannedBase, t0: float) -> BaseDeviation | None:
    """Deviation of the measured base from the plan, from ``t0`` (bag s, trajectory time 0) on.

    After the plan's last knot the planned pose is held (the robot should stand still there).
    """
    if len(planned.times) == 0 or len(pose.t) == 0:
        return None
    tau = pose.t - t0
    keep = tau >= 0.0
    if not keep.any():
        return None
    tau = tau[keep]
    plan = interpolate_clamped(planned.times, planned.positions, tau)
    return BaseDeviation(tau, pose.position[keep] - plan, float(planned.times[-1]))


@dataclass(frozen=True)
class FallCheck:
    """Whether (and when, bag s) the base dropped too low or tilted too far."""

    fell: bool
    t: float | None
    reason: str
    min_height_ratio: float
    max_tilt_deg: float
    height_reference: str


def tilt_deg(quaternion_xyzw: FloatArray) -> FloatArray:
    """Angle between the base z axis and the world z axis (deg), per row of unit quaternions."""
    q = quaternion_xyzw / np.linalg.norm(quaternion_xyzw, axis=1, keepdims=True)
    cos = 1.0 - 2.0 * (q[:, 0] ** 2 + q[:, 1] ** 2)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def detect_fall(
    pose: PoseSeries,
    planned: PlannedBase | None,
    t0: float | None,
    height_fraction: float = FALL_HEIGHT_FRACTION,
    max_tilt: float = FALL_TILT_DEG,
) -> FallCheck:
    """Fell = base height below ``height_fraction`` of the planned height (at the same trajectory time;
    the initial measured height without a plan) or base tilt beyond ``max_tilt`` deg, at any sample."""
    if planned is not None and len(planned.times) and t0 is not None:
        reference = interpolate_clamped(planned.times, planned.positions[:, 2:3], pose.t - t0)[:, 0]
        what = "planned base height"
    else:
        first = pose.t <= pose.t[0] + 0.1
        reference = np.full(len(pose.t), float(np.median(pose.position[first, 2])))
        what = "initial base height"
    ratio = np.divide(pose.position[:, 2], reference, out=np.ones(len(pose.t)), where=reference > 0)
    tilt = tilt_deg(pose.quaternion_xyzw)
    low, tilted = ratio < height_fraction, tilt > max_tilt
    bad = np.flatnonzero(low | tilted)
    if not len(bad):
        return FallCheck(False, None, "", float(ratio.min()), float(tilt.max()), what)
    i = int(bad[0])
    reason = (
        f"base height {pose.position[i, 2]:.3f} m is {ratio[i]:.1%} of the {what} ({reference[i]:.3f} m)"
        if low[i]
        else f"base tilted {tilt[i]:.0f} deg"
    )
    return FallCheck(True, float(pose.t[i]), reason, float(ratio.min()), float(tilt.max()), what)


# --- timing ------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LoopTiming:
    """A node's 1 kHz loop as its diagnostics reported it over the recording."""

    node: str
    reports: int
    rate_hz: float
    jitter_p99_us: float
    jitter_max_us: float
    deadline_misses: int
    scheduling: str = ""
    """What the OS granted the loop thread, as last reported (e.g. 'SCHED_FIFO 50, memory locked, CPUs kept from
    deep idle')."""
    latency_p99_us: float = np.nan
    """Telemetry-to-command latency (the control cycle: read to write), worst p99 over the reports."""
    cycle_p99_us: float = np.nan
    """Duration of the cycle's work, worst p99 over the reports."""
    run_jitter_p99_us: float = np.nan
    """Jitter p99 over the whole run, from the loop's run-long histogram (the upper edge of the bucket holding it)."""
    periods_over_2ms: int = -1
    """Periods longer than 2 ms over the whole run (-1: not reported)."""


def _float(values: Mapping[str, str], key: str) -> float:
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return np.nan


def loop_timing(diagnostics: Iterable[DiagnosticRecord]) -> list[LoopTiming]:
    """Per diagnostic status with ``loop.*`` keys: median rate, worst p99 / max jitter, last deadline misses."""
    per_node: dict[str, list[DiagnosticRecord]] = {}
    for d in diagnostics:
        if LoopKeys.RATE_HZ in d.values:
            per_node.setdefault(d.name, []).append(d)
    out = []
    for node, reports in per_node.items():
        rates = np.array([_float(r.values, LoopKeys.RATE_HZ) for r in reports])
        running = rates[np.isfinite(rates) & (rates > 0)]
        p99 = np.array([_float(r.values, LoopKeys.JITTER_P99_US) for r in reports])
        peak = np.array([_float(r.values, LoopKeys.JITTER_MAX_US) for r in reports])
        misses = _float(reports[-1].values, LoopKeys.DEADLINE_MISSES)
        latency = np.array([_float(r.values, ControlKeys.telemetry_to_command("p99_us")) for r in reports])
        cycle = np.array([_float(r.values, ControlKeys.cycle("p99_us")) for r in reports])
        histogram = parse_jitter_histogram(reports[-1].values.get(LoopKeys.JITTER_HISTOGRAM, ""))
        out.append(
            LoopTiming(
                node,
                len(reports),
                float(np.median(running)) if len(running) else np.nan,
                float(np.nanmax(p99)) if np.isfinite(p99).any() else np.nan,
                float(np.nanmax(peak)) if np.isfinite(peak).any() else np.nan,
                int(misses) if np.isfinite(misses) else -1,
                str(reports[-1].values.get(LoopKeys.REALTIME, "")),
                _worst(latency[latency > 0]),
                _worst(cycle[cycle > 0]),
                jitter_percentile_us(histogram, 99) if histogram is not None else np.nan,
                jitter_above_us(histogram, 1000) if histogram is not None else -1,
            )
        )
    return out


def _worst(values: FloatArray) -> float:
    """The largest finite value (NaN when there is none)."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if len(finite) else np.nan


@dataclass(frozen=True)
class StreamTiming:
    """How a recorded stream arrived: count, mean rate and periods between consecutive samples (ms)."""

    topic: str
    count: int
    rate_hz: float
    period_p50_ms: float
    period_p99_ms: float
    max_gap_ms: float
    time_source: str


def stream_timing(series: JointSeries | PoseSeries) -> StreamTiming:
    """Sample periods of a stream on the wall clock (from its times: sender stamps where the publisher set them),
    also when the report's time axis is the simulation's: a 1 kHz loop is 1 kHz of wall time."""
    t = series.wall_t if series.wall_t is not None else series.t
    if len(t) < 2:
        return StreamTiming(series.topic, len(t), np.nan, np.nan, np.nan, np.nan, series.time_source)
    periods = np.diff(t) * 1e3
    p50, p99 = np.percentile(periods, [50, 99])
    rate = (len(t) - 1) / (t[-1] - t[0]) if t[-1] > t[0] else np.nan
    return StreamTiming(
        series.topic, len(t), float(rate), float(p50), float(p99), float(periods.max()), series.time_source
    )


# --- faults ------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Fault:
    """Something that went wrong, with when it was first and last seen (bag s) and how many reports said so."""

    source: str
    text: str
    first_t: float
    last_t: float
    count: int


@dataclass(frozen=True)
class Transition:
    """A change of the stabilizer's state machine as its diagnostics showed it (1 s resolution)."""

    t: float
    state: str
    reason: str


_DETAIL_PREFIXES: Final = (MapperKeys.REJECTED_PREFIX, MapperKeys.CLAMPED_PREFIX, DriverKeys.CLAMPED_PREFIX)
_DETAIL_KEYS: Final = (DriverKeys.BOARD_ERRORS, StabilizerKeys.LOOP_ERROR, DriverKeys.SAFE_HOLD)


def is_stabilizer_status(name: str) -> bool:
    """Whether ``name`` is the stabilizer's own status (``rh5/stabilizer``, also under another prefix)."""
    return name.rstrip("/").endswith(STABILIZER_NODE)


def stabilizer_transitions(diagnostics: Iterable[DiagnosticRecord]) -> list[Transition]:
    """State changes of every status whose name ends in ``stabilizer`` and carries a ``state`` key."""
    out: list[Transition] = []
    for d in diagnostics:
        if is_stabilizer_status(d.name) and StabilizerKeys.STATE in d.values:
            state = d.values[StabilizerKeys.STATE]
            if not out or out[-1].state != state:
                out.append(Transition(d.t, state, d.values.get(StabilizerKeys.REASON, "")))
    return out


def _details(values: Mapping[str, str], message: str) -> str:
    """Non-zero rejection/clamping counters and error texts of a status (those its message does not repeat)."""
    parts = [f"{k}={v}" for k, v in values.items() if k.startswith(_DETAIL_PREFIXES) and v not in ("0", "0.0", "")]
    parts += [
        f"{k}: {values[k]}"
        for k in _DETAIL_KEYS
        if values.get(k) not in (None, "", "None") and values[k] not in message
    ]
    return "; ".join(parts)


def faults(diagnostics: Sequence[DiagnosticRecord], estopped: BoolSeries | None) -> list[Fault]:
    """Every distinct WARN/ERROR/STALE diagnostic (minus a normal end of playback), stabilizer
    transitions to holding/stopped for a reason other than a request, and emergency stops."""
    seen: dict[tuple[str, str], list[float]] = {}

    def note(source: str, text: str, t: float) -> None:
        seen.setdefault((source, text), []).append(t)

    for d in diagnostics:
        if d.level >= 1 and not (d.level == 1 and _reported_elsewhere(d.name)):
            detail = _details(d.values, d.message)
            note(d.name, f"{d.message} ({detail})" if detail else d.message, d.t)
    for tr in stabilizer_transitions(diagnostics):
        if tr.state in ("holding", "stopped") and not _benign(tr.reason):
            note("stabilizer", f"-> {tr.state}: {tr.reason}", tr.t)
    if estopped is not None:
        for t in estopped.t[estopped.value]:
            note(estopped.topic, "emergency stop latched", float(t))
    out = [Fault(src, text, min(ts), max(ts), len(ts)) for (src, text), ts in seen.items()]
    return sorted(out, key=lambda f: f.first_t)


def _reported_elsewhere(name: str) -> bool:
    """WARN statuses the report shows in another form: the stabilizer holding (its transitions) and a simulation
    slower than real time (the loop line's real-time factor)."""
    return (
        name.endswith(STABILIZER_NODE)
        or name.startswith(task_prefix(STABILIZER_NODE))
        or name == task_name(SIM_HARDWARE_NODE, PHYSICS_TASK)
    )


def _benign(reason: str) -> bool:
    return any(b in reason for b in BENIGN_REASONS)
