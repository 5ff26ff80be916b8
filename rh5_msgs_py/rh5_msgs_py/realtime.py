"""The 1 kHz machinery shared by the driver, the stabilizer and the simulated boards.

rclpy timers drop ticks at 1 kHz here (design/ros2_wheels.md, 3d), so each periodic loop
runs in its own thread on absolute deadlines in integer nanoseconds: advance the deadline
by one period, sleep until shortly before it, then spin the rest (``time.sleep`` alone
overshoots by 50-100 us). ROS callbacks hand data to the loop through a ``LatestValue``:
one slot that the loop reads without ever waiting for a writer.
"""

from __future__ import annotations

import ctypes
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

T = TypeVar("T")
PR_SET_TIMERSLACK = 29

SPIN_NS = 50_000  # busy-wait this long before each deadline (sleeps here overshoot by 50 us p50, 270 us p99;
# spinning through that would cost each 1 kHz loop a third of a core on a machine that has two)
TIMER_SLACK_NS = 1_000  # Linux's default 50 us timer slack would be most of the jitter budget
GIL_SWITCH_INTERVAL_S = 5e-5  # CPython's default 5 ms would let an executor thread delay a tick by 5 ms
STATS_WINDOW = 1000  # cycles kept for the jitter percentiles (1 s at 1 kHz)


class LatestValue(Generic[T]):
    """One slot holding the newest value and when it was written; readers never wait and never miss it.

    The slot is one immutable (value, stamp, version) tuple that ``set`` replaces in a single reference
    assignment (atomic under the GIL), so a reader always gets the last complete write. Writers take a lock
    among themselves only (the version count). A reader that found a writer's lock taken used to get nothing
    for that tick, which the stabilizer read as stale joint_states and held the robot (seen in a loaded
    fast_squats run) and the driver as a missing command (one HOLD cycle to the boards).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._slot: tuple[T | None, int, int] = (None, 0, 0)

    def set(self, value: T, stamp_ns: int | None = None) -> None:
        """Store ``value`` (an immutable snapshot), stamped now unless ``stamp_ns`` is given (monotonic ns)."""
        stamp = time.monotonic_ns() if stamp_ns is None else stamp_ns
        with self._lock:
            self._slot = (value, stamp, self._slot[2] + 1)

    def try_get(self) -> tuple[T | None, int, int]:
        """(value, stamp_ns, version) of the last complete write, without blocking (version 0: none yet)."""
        return self._slot

    def age_ns(self, now_ns: int | None = None) -> int | None:
        """How old the stored value is (None when nothing was ever stored)."""
        value, stamp, version = self.try_get()
        if version <= 0 or value is None:
            return None
        return (time.monotonic_ns() if now_ns is None else now_ns) - stamp


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


class LatencyWindow:
    """The latest durations (processing times, latencies) in ns, for p50/p99/max on /diagnostics."""

    def __init__(self, size: int = 2000) -> None:
        self._ns = np.zeros(size, dtype=np.int64)
        self._count = 0

    def add(self, ns: int) -> None:
        """Record one duration."""
        self._ns[self._count % len(self._ns)] = ns
        self._count += 1

    def percentiles_us(self) -> dict[str, float]:
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


def set_timer_slack(ns: int) -> bool:
    """Ask Linux to wake this thread from sleeps within ``ns`` of the deadline (prctl PR_SET_TIMERSLACK)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(ns), 0, 0, 0) == 0
    except (OSError, AttributeError):  # not Linux: keep the default slack
        return False


class LoopThread:
    """A named daemon thread that runs ``_loop`` until ``stop``: the start/stop, timing record and error hand-over
    that every loop of the suite shares. An exception that ends the loop is kept in ``error`` for the owner,
    which decides what a dead loop means. ``stop`` is idempotent."""

    def __init__(self, period_ns: int, name: str) -> None:
        self.period_ns = period_ns
        self.timer = LoopTimer(period_ns)
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the loop thread (and make the interpreter hand the GIL over often enough for 1 kHz)."""
        sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_INTERVAL_S))
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Ask the loop to stop and wait for it."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout_s)

    @property
    def running(self) -> bool:
        """Whether the loop thread is alive."""
        return self._thread.is_alive()

    def stats(self) -> LoopStats:
        """Timing of the latest cycles."""
        return self.timer.stats()

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as err:  # surfaced to the owner
            self.error = err
            raise

    def _loop(self) -> None:
        """The loop body: run until ``self._stop`` is set, recording each cycle in ``self.timer``."""
        raise NotImplementedError


class DeadlineLoop(LoopThread):
    """Calls ``step(now_ns, period_ns)`` every period from a dedicated thread, on absolute deadlines.

    A step that overruns its deadline is counted as a deadline miss; the schedule then
    skips the lost ticks instead of bursting to catch up.
    """

    def __init__(self, rate_hz: float, step: Callable[[int, int], None], name: str = "rh5-loop") -> None:
        if not rate_hz > 0:
            msg = f"rate_hz must be positive, got {rate_hz}"
            raise ValueError(msg)
        super().__init__(round(1e9 / rate_hz), name)
        self._step = step

    def _loop(self) -> None:
        set_timer_slack(TIMER_SLACK_NS)
        period = self.period_ns
        deadline = time.monotonic_ns() + period
        while not self._stop.is_set():
            remaining = deadline - time.monotonic_ns()
            if remaining > SPIN_NS:
                time.sleep((remaining - SPIN_NS) / 1e9)
            while time.monotonic_ns() < deadline:
                time.sleep(0)  # yields the GIL: other loops of the process must not wait for this spin
            now = time.monotonic_ns()
            self.timer.record(now)
            self._step(now, period)
            deadline += period
            finished = time.monotonic_ns()
            if finished > deadline:
                missed = (finished - deadline) // period + 1
                self.timer.deadline_misses += int(missed)
                deadline += int(missed) * period
