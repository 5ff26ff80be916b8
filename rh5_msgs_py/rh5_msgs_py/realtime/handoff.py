"""Hand-overs between a real-time loop and the process's other threads, where the loop never waits.

ROS callbacks hand data to a loop through a ``LatestValue`` (one slot the loop reads without waiting for a writer);
the loop hands its topics to a ``RealtimePublisher``, whose thread publishes them and which drops a sample rather
than make the loop wait.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from typing import Generic, TypeVar

from rh5_msgs_py.realtime.timing import LatencyWindow

__all__ = ["LatestValue", "RealtimePublisher"]

T = TypeVar("T")


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
