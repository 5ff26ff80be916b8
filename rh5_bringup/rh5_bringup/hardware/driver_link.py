"""The driver's link to the boards as the lifecycle wants it: opened by configure, closed by cleanup/shutdown.

``SwitchableLink`` stands where ``DriverCore`` expects its transport. While closed it sends nothing and receives
nothing (the boards then hold on their own command timeout); ``open`` builds the real transport (UDP or CAN) and
``close`` shuts it down. The 1 kHz cycle and the lifecycle callbacks run in different threads: a lock makes a
close wait for the send or receive in flight (tens of microseconds), so the cycle never uses a closed socket.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from types import SimpleNamespace
from typing import Any

from rh5_bringup.hardware.transports.base import Transport

_NO_STATS = SimpleNamespace(decoder=SimpleNamespace(garbage_bytes=0, senders={}))


class SwitchableLink:
    """A transport that can be opened and closed while a cycle uses it."""

    def __init__(self, opener: Callable[[], Transport]) -> None:
        self._opener = opener
        self._link: Transport | None = None
        self._last: Transport | None = None
        self._lock = threading.Lock()

    @property
    def is_open(self) -> bool:
        """Whether the link to the boards is up."""
        return self._link is not None

    def open(self) -> None:
        """Build the transport (idempotent); its errors (OSError, a bad CAN channel) propagate."""
        with self._lock:
            if self._link is None:
                self._link = self._last = self._opener()

    def close(self) -> None:
        """Shut the transport down (idempotent)."""
        with self._lock:
            link, self._link = self._link, None
            if link is not None:
                link.shutdown()

    def send_frames(self, frames: Sequence[bytes]) -> None:
        """Send when open; drop otherwise."""
        with self._lock:
            if self._link is not None:
                self._link.send_frames(frames)

    def recv(self, timeout: float = 0.0) -> list[Any]:
        """The frames waiting when open; none otherwise."""
        with self._lock:
            return self._link.recv(timeout=timeout) if self._link is not None else []

    def stats(self) -> Any:
        """The counters of the open (or last opened) transport."""
        link = self._last
        return link.stats() if link is not None else _NO_STATS

    def shutdown(self) -> None:
        """Close (the node's destroy)."""
        self.close()
