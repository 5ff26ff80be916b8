"""Keeps Python's cyclic garbage collector out of the real-time loops' cycles: off while a loop runs, the young
generations collected in the slack after a cycle instead."""

from __future__ import annotations

import gc
import threading
import time
from collections.abc import Sequence
from typing import ClassVar

from rh5_msgs_py.realtime.timing import LatencyWindow

__all__ = ["GC_COST_DECAY", "GC_FIRST_COST_NS", "GC_MARGIN_NS", "GC_OVERDUE", "GarbageCollection"]

GC_MARGIN_NS = 100_000  # a collection in a cycle's slack must leave this much of it free
GC_FIRST_COST_NS = (100_000, 300_000, 700_000)  # what each generation's collection is assumed to take until measured
GC_COST_DECAY = 0.999  # per collection: an expensive collection long ago stops holding a generation back
GC_OVERDUE = 20  # gen0 collections are forced once this many thresholds of allocations have piled up


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
