"""What a real-time loop asks of the OS: SCHED_FIFO for its thread, locked memory, a kept heap, CPUs kept out of
deep idle, a tight timer slack, and CPU affinity; every refusal is reported with its reason, never raised."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

__all__ = [
    "CPU_DMA_LATENCY",
    "HEAP_RESERVE_BYTES",
    "RTPRIO_FIX",
    "TIMER_SLACK_NS",
    "RealtimeGrant",
    "keep_cpus_awake",
    "keep_heap",
    "lock_memory",
    "pin_process",
    "request_realtime",
    "set_timer_slack",
]

PR_SET_TIMERSLACK = 29
TIMER_SLACK_NS = 1_000  # Linux's default 50 us timer slack would be most of the jitter budget
CPU_DMA_LATENCY = Path("/dev/cpu_dma_latency")  # Linux PM QoS: the longest wake-up from idle the CPUs may take
MCL_CURRENT, MCL_FUTURE = 1, 2  # mlockall flags (Linux <sys/mman.h>)
M_TRIM_THRESHOLD, M_MMAP_MAX = -1, -4  # mallopt parameters (glibc <malloc.h>)
HEAP_RESERVE_BYTES: Final = 64 * 2**20
"""Heap a real-time process faults in at start-up and keeps: room for a long trajectory's message and arrays."""
RTPRIO_FIX = (
    "grant real-time scheduling: on a robot PC add '@realtime - rtprio 99' and '@realtime - memlock unlimited' to "
    "/etc/security/limits.conf, add the user to the group 'realtime' and log in again (README, 'Real-time'); "
    "or run with CAP_SYS_NICE (e.g. as root)"
)


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
