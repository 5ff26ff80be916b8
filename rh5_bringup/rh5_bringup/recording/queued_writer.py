"""A bag writer in its own thread, fed through a queue: whoever receives messages never touches the disk.

Producers (the recorder's subscription callbacks) call :meth:`QueuedBagWriter.try_put`, which only
appends to a deque (or counts a drop when ``max_pending`` messages wait already). The thread wakes
every ``period_s``, writes everything queued, lets the bag close aged chunks, and on :meth:`stop`
drains the queue and closes the bag. It also counts gaps in each topic's publisher sequence numbers:
messages lost before they reached the recorder (meaningful for topics with one publisher; a topic
whose sequence ever steps back has several, and is left out).
"""

from __future__ import annotations

import threading
from collections import Counter, deque
from typing import Final

from rh5_bringup.recording.bag import BagWriter

__all__ = ["DEFAULT_MAX_PENDING", "QueuedBagWriter"]

DEFAULT_MAX_PENDING: Final = 100_000
"""Queued messages before new ones are dropped: 33 s of three 1 kHz streams, about 150 MB of JointStates."""

_Item = tuple[int, int, int, int, bytes]  # topic id, log time, publish time, sequence, data


class QueuedBagWriter:
    """Owns a :class:`BagWriter` (opened, topics added) and writes to it from a thread: start, try_put, stop."""

    def __init__(
        self, bag: BagWriter, *, max_pending: int = DEFAULT_MAX_PENDING, period_s: float = 0.01, name: str = "bag"
    ) -> None:
        if max_pending < 1:
            msg = f"max_pending must be at least 1, got {max_pending}"
            raise ValueError(msg)
        self.bag = bag
        self.max_pending = max_pending
        self.period_s = period_s
        self.dropped: Counter[int] = Counter()
        """Messages refused per topic id because the queue was full (or the writer stopped)."""
        self.high_water = 0
        """The most messages that waited at once."""
        self.error: BaseException | None = None
        """What ended the writer thread early (the bag is then aborted, readable up to its last chunk)."""
        self._queue: deque[_Item] = deque()
        self._accepting = True
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"{name}-writer", daemon=True)
        self._last_sequence: dict[int, int] = {}
        self._gaps: Counter[int] = Counter()
        self._several_publishers: set[int] = set()

    def start(self) -> None:
        """Start the writer thread."""
        self._thread.start()

    def try_put(self, topic_id: int, log_time: int, publish_time: int, sequence: int, data: bytes) -> bool:
        """Queue one message without blocking; False (and counted in ``dropped``) when it cannot be taken."""
        if self._accepting and len(self._queue) < self.max_pending:
            self._queue.append((topic_id, log_time, publish_time, sequence, data))
            return True
        self.dropped[topic_id] += 1
        return False

    def stop(self, timeout_s: float | None = 30.0) -> None:
        """Refuse new messages, write the queued ones, close the bag and end the thread. Idempotent.

        Call it once the producers have stopped (after the executor's last callback).
        """
        self._accepting = False
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        elif self._thread.ident is None:  # never started: close the bag here
            self._drain()
            self.bag.close()

    @property
    def pending(self) -> int:
        """Messages waiting in the queue now."""
        return len(self._queue)

    @property
    def sequence_gaps(self) -> dict[int, int]:
        """Publisher sequence numbers skipped, per topic id, for topics with one publisher."""
        return {tid: n for tid, n in self._gaps.items() if tid not in self._several_publishers}

    def _drain(self) -> None:
        queue, write, last = self._queue, self.bag.write, self._last_sequence
        count = len(queue)
        self.high_water = max(self.high_water, count)
        for _ in range(count):
            topic_id, log_time, publish_time, sequence, data = queue.popleft()
            write(topic_id, log_time, data, publish_time, sequence)
            previous = last.get(topic_id)
            if previous is not None:
                if sequence > previous + 1:
                    self._gaps[topic_id] += sequence - previous - 1
                elif sequence <= previous:
                    self._several_publishers.add(topic_id)
            last[topic_id] = sequence

    def _run(self) -> None:
        try:
            while True:
                stopping = self._stop.is_set()
                self._drain()
                self.bag.poll()
                if stopping and not self._queue:
                    break
                self._stop.wait(self.period_s)
            self.bag.close()
        except BaseException as err:  # disk full, bag error: keep what is written, report it
            self.error = err
            self._accepting = False
            self.bag.abort()
