"""The periodic loop threads: ``LoopThread`` (start, stop, timing record, real-time request, error hand-over) and
``DeadlineLoop``, which calls a step every period on absolute deadlines in integer nanoseconds."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from rh5_msgs_py.diagnostic_keys import LoopKeys
from rh5_msgs_py.realtime.collector import GarbageCollection
from rh5_msgs_py.realtime.scheduling import TIMER_SLACK_NS, RealtimeGrant, keep_heap, request_realtime, set_timer_slack
from rh5_msgs_py.realtime.timing import LatencyWindow, LoopStats, LoopTimer, jitter_histogram_text, loop_stats_values

__all__ = ["GIL_SWITCH_INTERVAL_S", "SPIN_NS", "DeadlineLoop", "LoopThread"]

SPIN_NS = 50_000  # busy-wait this long before each deadline (sleeps here overshoot by 50 us p50, 270 us p99;
# spinning through that would cost each 1 kHz loop a third of a core on a machine that has two)
GIL_SWITCH_INTERVAL_S = 5e-5  # CPython's default 5 ms would let an executor thread delay a tick by 5 ms


class LoopThread:
    """A named daemon thread that runs ``_loop`` until ``stop``: the start/stop, timing record and error hand-over
    that every loop of the suite shares. An exception that ends the loop is kept in ``error`` for the owner,
    which decides what a dead loop means. ``stop`` is idempotent.

    ``priority`` > 0 asks for SCHED_FIFO for the loop thread (``request_realtime``) and keeps the garbage
    collector out of the cycles; the outcome is in ``realtime`` once the thread has started, and
    ``on_realtime`` hears it first (the owner logs a refusal, which names the fix).
    """

    def __init__(
        self,
        period_ns: int,
        name: str,
        *,
        priority: int = 0,
        on_realtime: Callable[[RealtimeGrant], None] | None = None,
    ) -> None:
        self.period_ns = period_ns
        self.priority = priority
        self.timer = LoopTimer(period_ns)
        self.error: BaseException | None = None
        self.realtime: RealtimeGrant | None = None
        self.gc_pauses = tuple(LatencyWindow(200) for _ in range(3))  # per generation
        self._on_realtime = on_realtime
        self._granted = threading.Event()
        self._idle = threading.Event()
        self._idle.set()
        self.next_wake_ns = 0
        """When the loop next needs the interpreter (monotonic ns; 0: not scheduled yet)."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the loop thread (and make the interpreter hand the GIL over often enough for 1 kHz). With a
        priority, the caller's heap is kept (``keep_heap``): the thread that starts the loop also runs the
        executor, which takes the big messages."""
        sys.setswitchinterval(min(sys.getswitchinterval(), GIL_SWITCH_INTERVAL_S))
        if self.priority > 0:
            GarbageCollection.acquire()
            keep_heap()
        self._thread.start()

    def wait_for_realtime(self, timeout_s: float = 2.0) -> RealtimeGrant | None:
        """The grant, once the thread has asked for it (None if it has not within ``timeout_s``)."""
        self._granted.wait(timeout_s)
        return self.realtime

    def stop(self, timeout_s: float = 2.0) -> None:
        """Ask the loop to stop and wait for it."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout_s)
        self._idle.set()  # nobody waits for a stopped loop

    def wait_for_slack(self, min_ns: int, timeout_s: float = 0.1) -> bool:
        """Block until the loop is between cycles with at least ``min_ns`` before its next wake-up.

        The process's other threads (publisher, executor) call this before a piece of work, so that the loop
        does not find the interpreter lock taken when it wakes or while it computes: Python runs one thread at
        a time, and a thread that holds the lock delays the loop by up to the switch interval at every hand-over.
        False after ``timeout_s`` (a loop that stopped or overruns leaves the caller to go on anyway).
        """
        deadline = time.monotonic_ns() + int(timeout_s * 1e9)
        while not self._stop.is_set():
            now = time.monotonic_ns()
            if now >= deadline:
                return False
            if not self._idle.wait((deadline - now) / 1e9):
                return False
            now = time.monotonic_ns()
            if self.next_wake_ns - now >= min_ns:
                return True
            time.sleep(max(self.next_wake_ns - now, 0) / 1e9 + 20e-6)  # past the wake-up: the cycle then runs
        return True

    @property
    def running(self) -> bool:
        """Whether the loop thread is alive."""
        return self._thread.is_alive()

    def stats(self) -> LoopStats:
        """Timing of the latest cycles."""
        return self.timer.stats()

    def diagnostics(self) -> dict[str, object]:
        """``loop.*`` values for /diagnostics: timing, the real-time grant and the garbage collector's pauses."""
        values = loop_stats_values(self.stats())
        grant = self.realtime
        values[LoopKeys.REALTIME] = "pending" if grant is None else grant.describe()
        values[LoopKeys.REALTIME_GRANTED] = bool(grant is not None and grant.granted)
        values[LoopKeys.JITTER_HISTOGRAM] = jitter_histogram_text(self.timer.jitter_counts)
        for generation, window in enumerate(self.gc_pauses):
            values[LoopKeys.gc_collections(generation)] = window.count
            values.update({LoopKeys.gc_pause(generation, k): round(v, 1) for k, v in window.percentiles_us().items()})
        return values

    def _run(self) -> None:
        try:
            self.realtime = request_realtime(self.priority)
            self._granted.set()
            if self._on_realtime is not None:
                self._on_realtime(self.realtime)
            self._loop()
        except BaseException as err:  # surfaced to the owner
            self.error = err
            raise
        finally:
            self._granted.set()
            if self.priority > 0:
                GarbageCollection.release()

    def _loop(self) -> None:
        """The loop body: run until ``self._stop`` is set, recording each cycle in ``self.timer``."""
        raise NotImplementedError


class DeadlineLoop(LoopThread):
    """Calls ``step(now_ns, period_ns)`` every period from a dedicated thread, on absolute deadlines.

    A step that overruns its deadline is counted as a deadline miss; the schedule then
    skips the lost ticks instead of bursting to catch up.
    """

    def __init__(
        self,
        rate_hz: float,
        step: Callable[[int, int], None],
        name: str = "rh5-loop",
        *,
        priority: int = 0,
        on_realtime: Callable[[RealtimeGrant], None] | None = None,
    ) -> None:
        if not rate_hz > 0:
            msg = f"rate_hz must be positive, got {rate_hz}"
            raise ValueError(msg)
        super().__init__(round(1e9 / rate_hz), name, priority=priority, on_realtime=on_realtime)
        self._step = step

    def _loop(self) -> None:
        set_timer_slack(TIMER_SLACK_NS)
        realtime = self.realtime is not None and self.realtime.granted
        spin_ns = 0 if realtime else SPIN_NS  # under SCHED_FIFO the sleep itself wakes within microseconds
        collect = self.priority > 0
        period = self.period_ns
        deadline = time.monotonic_ns() + period
        while not self._stop.is_set():
            remaining = deadline - time.monotonic_ns()
            if remaining > spin_ns:
                time.sleep((remaining - spin_ns) / 1e9)
            while time.monotonic_ns() < deadline:
                time.sleep(0)  # yields the GIL: other loops of the process must not wait for this spin
            now = time.monotonic_ns()
            self._idle.clear()
            self.timer.record(now)
            self._step(now, period)
            deadline += period
            finished = time.monotonic_ns()
            if finished > deadline:
                missed = (finished - deadline) // period + 1
                self.timer.deadline_misses += int(missed)
                deadline += int(missed) * period
            elif collect:
                GarbageCollection.collect_in_slack(deadline - finished, self.gc_pauses)
            self.next_wake_ns = deadline
            self._idle.set()
