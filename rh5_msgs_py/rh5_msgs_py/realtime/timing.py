"""Timing records of the periodic loops: wake-ups to rate, period and jitter (LoopTimer, LoopStats), duration
windows for p50/p99/max (LatencyWindow), and the run-long jitter histogram as /diagnostics carries it."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np

from rh5_msgs_py.diagnostic_keys import LoopKeys, Percentile

__all__ = [
    "JITTER_EDGES_US",
    "STATS_WINDOW",
    "LatencyWindow",
    "LoopStats",
    "LoopTimer",
    "jitter_above_us",
    "jitter_histogram_text",
    "jitter_percentile_us",
    "loop_stats_values",
    "parse_jitter_histogram",
]

STATS_WINDOW = 1000  # cycles kept for the jitter percentiles (1 s at 1 kHz)
JITTER_EDGES_US: Final = (10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 125, 150, 200, 300, 500, 1000, 2000, 5000)
"""Upper edges of the run-long jitter histogram's buckets (one more bucket holds everything above the last)."""


@dataclass(frozen=True)
class LoopStats:
    """Timing of a periodic loop over its latest window of cycles."""

    cycles: int
    rate_hz: float
    period_p50_us: float
    period_p99_us: float
    period_max_us: float
    jitter_p50_us: float
    jitter_p99_us: float
    jitter_max_us: float
    deadline_misses: int

    def as_dict(self) -> dict[str, float]:
        """For diagnostics key/values and summaries."""
        return {k: round(v, 2) if isinstance(v, float) else v for k, v in self.__dict__.items()}


def loop_stats_values(stats: LoopStats) -> dict[str, object]:
    """``stats`` as ``loop.*`` values for /diagnostics (floats rounded as ``LoopStats.as_dict`` rounds them)."""
    return {
        LoopKeys.CYCLES: stats.cycles,
        LoopKeys.RATE_HZ: round(stats.rate_hz, 2),
        LoopKeys.PERIOD_P50_US: round(stats.period_p50_us, 2),
        LoopKeys.PERIOD_P99_US: round(stats.period_p99_us, 2),
        LoopKeys.PERIOD_MAX_US: round(stats.period_max_us, 2),
        LoopKeys.JITTER_P50_US: round(stats.jitter_p50_us, 2),
        LoopKeys.JITTER_P99_US: round(stats.jitter_p99_us, 2),
        LoopKeys.JITTER_MAX_US: round(stats.jitter_max_us, 2),
        LoopKeys.DEADLINE_MISSES: stats.deadline_misses,
    }


class LatencyWindow:
    """The latest durations (processing times, latencies) in ns, for p50/p99/max on /diagnostics."""

    def __init__(self, size: int = 2000) -> None:
        self._ns = np.zeros(size, dtype=np.int64)
        self._count = 0

    def add(self, ns: int) -> None:
        """Record one duration."""
        self._ns[self._count % len(self._ns)] = ns
        self._count += 1

    def add_many(self, ns: np.ndarray) -> None:
        """Record several durations at once (the newest window's worth if more)."""
        ns = np.asarray(ns, dtype=np.int64)[-len(self._ns) :]
        self._ns[(self._count + np.arange(len(ns))) % len(self._ns)] = ns
        self._count += len(ns)

    @property
    def count(self) -> int:
        """Durations recorded since the start (the window keeps the latest)."""
        return self._count

    def percentiles_us(self) -> dict[Percentile, float]:
        """p50, p99 and max of the window in microseconds (empty window: zeros)."""
        window = self._ns[: min(self._count, len(self._ns))]
        if not len(window):
            return {"p50_us": 0.0, "p99_us": 0.0, "max_us": 0.0}
        p50, p99 = np.percentile(window, [50, 99]) / 1e3
        return {"p50_us": float(p50), "p99_us": float(p99), "max_us": float(window.max() / 1e3)}


class LoopTimer:
    """Records wake-up times of a periodic loop and turns them into LoopStats."""

    def __init__(self, period_ns: int, window: int = STATS_WINDOW) -> None:
        self.period_ns = period_ns
        self._wakes = np.zeros(window + 1, dtype=np.int64)
        self._lock = threading.Lock()
        self._count = 0
        self.deadline_misses = 0
        self.jitter_counts = np.zeros(len(JITTER_EDGES_US) + 1, dtype=np.int64)
        """Periods per jitter bucket since the loop started (``JITTER_EDGES_US``), binned by ``stats``."""
        self._binned = 1  # wake-ups whose period is in jitter_counts (the first wake-up has none)

    def record(self, wake_ns: int) -> None:
        """Note one cycle's wake-up time (monotonic ns)."""
        with self._lock:  # uncontended except while stats() copies the window
            self._wakes[self._count % len(self._wakes)] = wake_ns
            self._count += 1

    def stats(self) -> LoopStats:
        """Rate, period and jitter percentiles of the window (|period - nominal| is the jitter)."""
        with self._lock:  # a consistent snapshot: the loop thread records while we read
            count, all_wakes = self._count, self._wakes.copy()
        n = min(count, len(all_wakes))
        if n < 2:
            return LoopStats(count, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, self.deadline_misses)
        start = count - n
        wakes = all_wakes[(start + np.arange(n)) % len(all_wakes)]
        periods = np.diff(wakes) / 1e3
        jitter = np.abs(periods - self.period_ns / 1e3)
        self._bin(jitter, count)
        rate = (n - 1) / ((wakes[-1] - wakes[0]) / 1e9)
        p50, p99 = np.percentile(periods, [50, 99])
        j50, j99 = np.percentile(jitter, [50, 99])
        return LoopStats(
            count,
            float(rate),
            float(p50),
            float(p99),
            float(periods.max()),
            float(j50),
            float(j99),
            float(jitter.max()),
            self.deadline_misses,
        )

    def _bin(self, window_jitter: np.ndarray, count: int) -> None:
        """Add the periods of the window not binned yet to ``jitter_counts`` (a loop whose stats are read at least
        once per window, as /diagnostics does every second, has every period binned)."""
        with self._lock:  # two readers may bin at once: each takes the periods after the other's
            new = min(count - self._binned, len(window_jitter))
            if new <= 0:
                return
            self._binned = count
        buckets = np.searchsorted(JITTER_EDGES_US, window_jitter[-new:], side="left")
        self.jitter_counts += np.bincount(buckets, minlength=len(self.jitter_counts))


def jitter_histogram_text(counts: Sequence[int]) -> str:
    """The histogram as its /diagnostics value (``loop.jitter_histogram``): the counts, space-separated."""
    return " ".join(map(str, counts))


def parse_jitter_histogram(text: str) -> np.ndarray | None:
    """The counts of a ``loop.jitter_histogram`` value; None when it is not one (another length, not integers)."""
    try:
        counts = np.array([int(c) for c in text.split()], dtype=np.int64)
    except ValueError:
        return None
    return counts if len(counts) == len(JITTER_EDGES_US) + 1 else None


def jitter_above_us(counts: Sequence[int], edge_us: int) -> int:
    """The periods whose jitter exceeds ``edge_us`` (one of ``JITTER_EDGES_US``): at 1 kHz, 1000 counts the periods
    over 2 ms."""
    return int(np.asarray(counts)[JITTER_EDGES_US.index(edge_us) + 1 :].sum())


def jitter_percentile_us(counts: Sequence[int], q: float) -> float:
    """The upper edge of the histogram bucket holding the ``q``-th percentile of the binned jitter (``inf``: above the
    last edge; NaN: nothing binned)."""
    counts = np.asarray(counts, dtype=np.int64)
    total = int(counts.sum())
    if total == 0:
        return float("nan")
    bucket = int(np.searchsorted(np.cumsum(counts), q / 100 * total, side="left"))
    return float(JITTER_EDGES_US[bucket]) if bucket < len(JITTER_EDGES_US) else float("inf")
