"""The 1 kHz machinery shared by the control cycle, the driver, the stabilizer and the simulated boards.

rclpy timers drop ticks at 1 kHz here (design/ros2_wheels.md, 3d), so each periodic loop
runs in its own thread on absolute deadlines in integer nanoseconds. A loop given a real-time
priority asks for ``SCHED_FIFO`` for its thread only, locks the process's memory, keeps the CPUs
out of deep idle states and keeps the garbage collector out of its cycles (``request_realtime``,
``GarbageCollection``); under ``SCHED_FIFO`` a plain sleep to the deadline wakes within microseconds.
Without it (refused by the OS, or priority 0) the loop sleeps until shortly before the deadline and
spins the rest (``time.sleep`` alone overshoots by 50-100 us there). ROS callbacks hand data to the loop
through a ``LatestValue``: one slot that the loop reads without ever waiting for a writer; the
loop hands its topics to a ``RealtimePublisher``, whose thread publishes them and which drops a
sample rather than make the loop wait.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import gc
import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Final, Generic, TypeVar

import numpy as np

from rh5_msgs_py.diagnostic_keys import LoopKeys, Percentile

T = TypeVar("T")
PR_SET_TIMERSLACK = 29

SPIN_NS = 50_000  # busy-wait this long before each deadline (sleeps here overshoot by 50 us p50, 270 us p99;
# spinning through that would cost each 1 kHz loop a third of a core on a machine that has two)
TIMER_SLACK_NS = 1_000  # Linux's default 50 us timer slack would be most of the jitter budget
CPU_DMA_LATENCY = Path("/dev/cpu_dma_latency")  # Linux PM QoS: the longest wake-up from idle the CPUs may take
GIL_SWITCH_INTERVAL_S = 5e-5  # CPython's default 5 ms would let an executor thread delay a tick by 5 ms
STATS_WINDOW = 1000  # cycles kept for the jitter percentiles (1 s at 1 kHz)
JITTER_EDGES_US: Final = (10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 125, 150, 200, 300, 500, 1000, 2000, 5000)
"""Upper edges of the run-long jitter histogram's buckets (one more bucket holds everything above the last)."""
MCL_CURRENT, MCL_FUTURE = 1, 2  # mlockall flags (Linux <sys/mman.h>)
M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4  # mallopt parameters (glibc <malloc.h>)
HEAP_RESERVE_BYTES: Final = 64 * 2**20
"""Heap a real-time process faults in at start-up and keeps: room for a long trajectory's message and arrays."""
RTPRIO_FIX = (
    "grant real-time scheduling: on a robot PC add '@realtime - rtprio 99' and '@realtime - memlock unlimited' to "
    "/etc/security/limits.conf, add the user to the group 'realtime' and log in again (README, 'Real-time'); "
    "or run with CAP_SYS_NICE (e.g. as root)"
)
GC_MARGIN_NS = 100_000  # a collection in a cycle's slack must leave this much of it free
GC_FIRST_COST_NS = (100_000, 300_000, 700_000)  # what each generation's collection is assumed to take until measured
GC_COST_DECAY = 0.999  # per collection: an expensive collection long ago stops holding a generation back
GC_OVERDUE = 20  # gen0 collections are forced once this many thresholds of allocations have piled up


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


def set_timer_slack(ns: int) -> bool:
    """Ask Linux to wake this thread from sleeps within ``ns`` of the deadline (prctl PR_SET_TIMERSLACK)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(ns), 0, 0, 0) == 0
    except (OSError, AttributeError):  # not Linux: keep the default slack
        return False


@dataclass(frozen=True)
class RealtimeGrant:
    """What the OS granted a loop thread: SCHED_FIFO at ``priority`` (0: normal scheduling), locked memory and
    CPUs kept out of idle states slow to wake from."""

    requested: int
    priority: int
    memory_locked: bool
    reason: str = ""
    """Why real-time was not granted (empty when it was, or when none was requested)."""
    idle_wakeup: str = ""
    """Empty when the CPUs are kept awake (PM QoS 0 us), else why not."""

    @property
    def granted(self) -> bool:
        """Whether the loop runs under SCHED_FIFO."""
        return self.priority > 0

    def describe(self) -> str:
        """One line for diagnostics and reports, e.g. 'SCHED_FIFO 50, memory locked, CPUs kept from deep idle'."""
        if self.granted:
            memory = "locked" if self.memory_locked else "not locked"
            idle = "CPUs kept from deep idle" if not self.idle_wakeup else f"CPU idle not limited ({self.idle_wakeup})"
            return f"SCHED_FIFO {self.priority}, memory {memory}, {idle}"
        if not self.requested:
            return "normal scheduling (not requested)"
        return f"normal scheduling: SCHED_FIFO {self.requested} refused ({self.reason})"


_memory_lock = threading.Lock()
_memory_locked: bool | None = None


def lock_memory() -> bool:
    """Lock the process's current and future pages in RAM (mlockall), once per process; False when refused.

    A page fault in a cycle (memory swapped out, or a fresh page touched) costs tens of microseconds to
    milliseconds; locked, every page the process maps is resident from then on.
    """
    global _memory_locked  # noqa: PLW0603 (one lock per process, whichever loop asks first)
    with _memory_lock:
        if _memory_locked is None:
            try:
                libc = ctypes.CDLL(None, use_errno=True)
                _memory_locked = libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0
            except (OSError, AttributeError):  # not Linux
                _memory_locked = False
        return _memory_locked


_heap_lock = threading.Lock()
_heap_kept: bool | None = None


def keep_heap(reserve_bytes: int = HEAP_RESERVE_BYTES) -> bool:
    """Make glibc's malloc keep the memory it has: big blocks from the heap instead of fresh mappings, freed memory
    never trimmed back to the OS, and ``reserve_bytes`` of it faulted in now (once per process, in the arena of
    the calling thread); False where malloc cannot be tuned (not glibc).

    The real-time Linux recipe (mlockall, no malloc trimming, no mmap, a prefaulted heap): under mlockall every
    page new to the process is faulted in when it is mapped, so a fresh 3.5 MB block (a 6300-point trajectory's
    message, taken under the interpreter lock) cost 3-5.5 ms here, and 0.4-1.1 ms from a kept heap.
    """
    global _heap_kept  # noqa: PLW0603 (one heap per process)
    with _heap_lock:
        if _heap_kept is None:
            try:
                libc = ctypes.CDLL(None, use_errno=True)
                _heap_kept = libc.mallopt(M_MMAP_MAX, 0) == 1 and libc.mallopt(M_TRIM_THRESHOLD, -1) == 1  # -1: never
            except (OSError, AttributeError):  # no mallopt: not glibc
                _heap_kept = False
            if _heap_kept and reserve_bytes > 0:
                reserve = bytearray(reserve_bytes)  # calloc: fresh heap is known to be zero and left untouched
                page = os.sysconf("SC_PAGE_SIZE")
                reserve[::page] = b"\1" * len(range(0, reserve_bytes, page))  # so touch every page; freed, it stays
                del reserve
        return _heap_kept


_idle_lock = threading.Lock()
_idle_request: tuple[int | None, str] | None = None


def keep_cpus_awake() -> str:
    """Ask Linux's PM QoS for 0 us wake-up latency from idle, once per process and for its life; "" when held, else
    why not.

    A CPU that idles between cycles halts, and waking it costs tens of microseconds to milliseconds (on this
    virtual machine a halted virtual CPU is often given to another guest: a bare SCHED_FIFO loop had jitter p99
    594 us and 257 periods over 2 ms per minute, with the request 60 us and 40). Held, idle CPUs poll instead,
    which costs power, not the other processes' CPU time. The request lasts while the file stays open, as
    cyclictest holds it; writing it needs root or write access to /dev/cpu_dma_latency.
    """
    global _idle_request  # noqa: PLW0603 (one request per process, whichever loop asks first)
    with _idle_lock:
        if _idle_request is None:
            fd = None
            try:
                fd = os.open(CPU_DMA_LATENCY, os.O_WRONLY | os.O_CLOEXEC)
                os.write(fd, (0).to_bytes(4, sys.byteorder))  # an s32 in microseconds; kept open on purpose
            except OSError as err:
                if fd is not None:
                    os.close(fd)
                _idle_request = (None, f"{CPU_DMA_LATENCY}: {err.strerror}")
            else:
                _idle_request = (fd, "")
        return _idle_request[1]


def request_realtime(priority: int) -> RealtimeGrant:
    """Put the calling thread under SCHED_FIFO at ``priority`` (1-99), lock memory and keep the CPUs awake
    (``keep_cpus_awake``); 0 asks for nothing.

    Only the calling thread is raised (Linux schedules threads, and pid 0 means the caller), so the
    process's other threads (executor, publisher) and the other processes keep normal priority.
    A refusal (no CAP_SYS_NICE and no rtprio limit: EPERM) is reported in the grant, never raised.
    """
    if priority <= 0:
        return RealtimeGrant(0, 0, False)
    if not hasattr(os, "sched_setscheduler"):
        return RealtimeGrant(priority, 0, False, "this OS has no SCHED_FIFO")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as err:
        why = "no permission" if err.errno == errno.EPERM else os.strerror(err.errno or 0)
        limit = _rtprio_limit()
        return RealtimeGrant(priority, 0, False, f"{why}; rtprio limit {limit}")
    return RealtimeGrant(priority, priority, lock_memory(), idle_wakeup=keep_cpus_awake())


def pin_process(cpus: Sequence[int]) -> list[int]:
    """Run every thread of this process, and the threads they start later, on ``cpus`` only; returns the CPUs set.

    ``cpus`` index the CPUs this process may use (negative from the end: -1 is the last), so a bringup can say
    "the last core" on any machine. A core kept for the real-time cycle stays free of the simulation's work and
    its caches stay warm: with the cycle alone on its core a run missed 2-3 times fewer deadlines here. Child
    processes started before the call keep their own affinity. ValueError names a CPU the process cannot use.
    """
    allowed = sorted(os.sched_getaffinity(0))
    chosen = set()
    for index in cpus:
        if not -len(allowed) <= index < len(allowed):
            msg = f"CPU index {index}: this process may use {len(allowed)} CPUs ({allowed})"
            raise ValueError(msg)
        chosen.add(allowed[index])
    for task in Path("/proc/self/task").iterdir():
        with contextlib.suppress(ProcessLookupError):  # a thread that ended meanwhile
            os.sched_setaffinity(int(task.name), chosen)
    return sorted(chosen)


def _rtprio_limit() -> str:
    """The process's RLIMIT_RTPRIO soft limit as text (for the refusal message)."""
    try:
        import resource  # noqa: PLC0415 (POSIX only)

        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    except (ImportError, AttributeError, OSError):
        return "unknown"
    return "unlimited" if soft == resource.RLIM_INFINITY else str(soft)


class GarbageCollection:
    """Keeps Python's cyclic garbage collector out of the loops' cycles, process-wide.

    While any loop holds it, automatic collection is off and everything allocated at start-up is frozen
    (``gc.freeze``: never scanned again); the loops collect the young generations in the slack after a
    cycle instead (``collect_in_slack``), where a collection cannot delay a deadline. The last loop to
    let go turns automatic collection back on.
    """

    _lock = threading.Lock()
    _holders = 0
    _was_enabled = True

    @classmethod
    def acquire(cls) -> None:
        """Freeze the start-up heap and turn automatic collection off (counted per loop)."""
        with cls._lock:
            if cls._holders == 0:
                cls._was_enabled = gc.isenabled()
                gc.disable()
                gc.collect()
                gc.freeze()
            cls._holders += 1

    @classmethod
    def release(cls) -> None:
        """Undo ``acquire``; the last holder unfreezes and re-enables automatic collection."""
        with cls._lock:
            cls._holders = max(0, cls._holders - 1)
            if cls._holders == 0:
                gc.unfreeze()
                if cls._was_enabled:
                    gc.enable()

    _cost_ns: ClassVar[list[float]] = list(GC_FIRST_COST_NS)
    """Per generation, a slowly decaying maximum of its collections' durations in this process."""

    @classmethod
    def collect_in_slack(cls, slack_ns: int, windows: Sequence[LatencyWindow]) -> None:
        """Collect, when the collector's thresholds say so, the oldest due generation whose collection is expected
        to fit in ``slack_ns`` (measured in the control process: 0.4-0.9 ms even for the young generation, the
        executor's allocations count too), and time it into ``windows[generation]``. A generation that does not
        fit waits for a cycle with more slack; young garbage is collected anyway once far overdue."""
        counts, thresholds = gc.get_count(), gc.get_threshold()
        if counts[0] < thresholds[0]:
            return
        due = 2 if counts[2] >= thresholds[2] else 1 if counts[1] >= thresholds[1] else 0
        fits = [g for g in range(due, -1, -1) if cls._cost_ns[g] + GC_MARGIN_NS <= slack_ns]
        if fits:
            generation = fits[0]
        elif counts[0] >= GC_OVERDUE * thresholds[0]:
            generation = 0
        else:
            return
        start = time.monotonic_ns()
        gc.collect(generation)
        took = time.monotonic_ns() - start
        cls._cost_ns[generation] = max(float(took), cls._cost_ns[generation] * GC_COST_DECAY)
        windows[generation].add(took)


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


class RealtimePublisher(Generic[T]):
    """Publishes what a real-time loop hands over, from a thread of its own; the loop never waits for it.

    ``try_publish`` queues the sample when the thread is idle and otherwise drops it (counted in
    ``dropped``): a slow publisher or a stalled DDS costs samples on the topics, never a cycle.
    The idea of realtime_tools' RealtimePublisher, with the message building moved out of the loop too.
    """

    def __init__(self, publish: Callable[[T], None], name: str = "rh5-publisher") -> None:
        self._publish = publish
        self._queue: queue.SimpleQueue[T | None] = queue.SimpleQueue()
        self._busy = False
        self.published = 0
        self.dropped = 0
        self.error: BaseException | None = None
        self.duration = LatencyWindow()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._stopped = False
        self.on_start: Callable[[], object] | None = None
        """Called first in the publishing thread (e.g. to set its scheduling)."""

    def start(self) -> None:
        """Start the publishing thread."""
        self._thread.start()

    def try_publish(self, sample: T) -> bool:
        """Hand ``sample`` over without blocking; False when it was dropped (the previous one is in flight)."""
        if self._busy or not self._queue.empty() or self._stopped:
            self.dropped += 1
            return False
        self._busy = True
        self._queue.put(sample)
        return True

    def stop(self, timeout_s: float = 2.0) -> None:
        """Publish what is queued, then end the thread (idempotent)."""
        if not self._stopped:
            self._stopped = True
            self._queue.put(None)
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout_s)

    def diagnostics(self) -> dict[str, object]:
        """``publish.*`` values for /diagnostics: samples published and dropped, time to publish one."""
        values: dict[str, object] = {"publish.published": self.published, "publish.dropped": self.dropped}
        values.update({f"publish.{k}": round(v, 1) for k, v in self.duration.percentiles_us().items()})
        if self.error is not None:
            values["publish.error"] = repr(self.error)
        return values

    def _run(self) -> None:
        if self.on_start is not None:
            self.on_start()
        while True:
            sample = self._queue.get()
            if sample is None:
                return
            start = time.monotonic_ns()
            try:
                self._publish(sample)
            except Exception as err:  # kept for diagnostics; the loop goes on without its topics
                self.error = err
            else:
                self.published += 1
            finally:
                self.duration.add(time.monotonic_ns() - start)
                self._busy = False
