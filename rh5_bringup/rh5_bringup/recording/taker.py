"""Raw subscriptions whose messages a thread takes in batches, outside any executor (the one rclpy module here).

An rclpy executor rebuilds its wait set at every wake-up, about 100-200 us of Python with the
recorder's 15 subscriptions, their QoS event handlers and the parameter services; at three 1 kHz
streams that alone took half a core of this machine (measured: 47 % for 2.1k msg/s). A recorder
needs no low latency, so its subscriptions sit in a callback group that no executor may run, and
a thread takes whatever arrived every ``period_s`` (7 % for 2.9k msg/s). DDS keeps the messages
meanwhile: the subscriptions' history depth must cover the period plus any stall of this process.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, Final

from rclpy.subscription import Subscription

from rh5_msgs_py.streams import NeverExecutedGroup

__all__ = ["DEFAULT_TAKE_PERIOD_S", "RawTaker"]

DEFAULT_TAKE_PERIOD_S: Final = 0.005
"""Take every 5 ms: 15 messages of three 1 kHz streams per pass, far below any history depth used."""

Deliver = Callable[[int, bytes, dict[str, Any]], None]
"""Receives (key, serialized message, rmw message info) for every message taken."""


class RawTaker:
    """Takes the messages of raw subscriptions (created in :attr:`callback_group`) from its own thread."""

    def __init__(self, deliver: Deliver, *, period_s: float = DEFAULT_TAKE_PERIOD_S, name: str = "raw-taker") -> None:
        self.callback_group = NeverExecutedGroup()
        self.period_s = period_s
        self.error: BaseException | None = None
        """What ended the thread early (e.g. the context shut down under a take)."""
        self._deliver = deliver
        self._subscriptions: list[tuple[int, Subscription]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._lock = threading.Lock()

    def add(self, key: int, subscription: Subscription) -> None:
        """Serve ``subscription`` (raw, in :attr:`callback_group`); its messages are delivered with ``key``."""
        if subscription.callback_group is not self.callback_group or not subscription.raw:
            msg = f"{subscription.topic_name}: subscribe raw and in the taker's callback group"
            raise ValueError(msg)
        with self._lock:
            self._subscriptions.append((key, subscription))

    def start(self) -> None:
        """Start taking."""
        self._thread.start()

    def take_all(self) -> int:
        """Take and deliver every message waiting in every subscription; returns how many."""
        taken = 0
        deliver = self._deliver
        with self._lock:
            for key, subscription in self._subscriptions:
                handle, msg_type = subscription.handle, subscription.msg_type
                with handle:
                    while (result := handle.take_message(msg_type, True)) is not None:
                        deliver(key, result[0], result[1])
                        taken += 1
        return taken

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the thread after one last pass (what arrived until now is delivered). Idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    def _run(self) -> None:
        try:
            while True:
                stopping = self._stop.is_set()
                self.take_all()
                if stopping:
                    return
                self._stop.wait(self.period_s)
        except Exception as err:  # a shut-down context or destroyed subscription: the owner reports it
            self.error = err
