"""1 kHz subscriptions served by a thread of their own instead of the rclpy executor.

The executor rebuilds its wait set from every entity of the node at each wake-up (100-200 us of Python
here); at two 1 kHz streams that alone is a third of a core. A `StreamThread` waits on just its own
subscriptions, with a wait set of fixed size, and runs their callbacks in its thread. The subscriptions
sit in a callback group no executor runs (`NeverExecutedGroup`), so the node's services, timers and
parameter events stay on the executor. Callbacks then run concurrently with the executor's, as they
would in a multi-threaded executor: they must only touch thread-safe state (e.g. `LatestValue`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import ExitStack, suppress
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription

from rh5_msgs_py.interfaces import Topic, message_class

WAIT_TIMEOUT_NS = 100_000_000
"""Wake up at least every 100 ms to notice a shut-down context."""


class NeverExecutedGroup(CallbackGroup):
    """A callback group executors never run nor wait on: its entities are served by their owner's thread."""

    def can_execute(self, entity: Any) -> bool:  # noqa: ARG002 (the interface of CallbackGroup)
        """Never: the executor leaves the entity out of its wait set."""
        return False

    def beginning_execution(self, entity: Any) -> bool:  # noqa: ARG002 (see can_execute)
        """Never."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Nothing began."""


class StreamThread:
    """Waits on a few subscriptions in a dedicated thread and calls their callbacks there."""

    def __init__(self, node: Node, name: str = "rh5-streams") -> None:
        self.node = node
        self.callback_group = NeverExecutedGroup()
        self.error: BaseException | None = None
        self._entries: list[tuple[Subscription, Callable[[Any], None]]] = []
        self._stop = threading.Event()
        self._wake = GuardCondition(None, self.callback_group, context=node.context)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def subscribe(self, topic: Topic, callback: Callable[[Any], None], *, raw: bool = False) -> Subscription:
        """Subscribe with the topic's contract type and QoS; ``callback`` runs in this thread from its next wait."""
        subscription = self.node.create_subscription(
            message_class(topic.type),
            topic.name,
            lambda _msg: None,  # never called: this thread takes the messages
            topic.qos,
            callback_group=self.callback_group,
            raw=raw,
        )
        self._entries = [*self._entries, (subscription, callback)]  # the thread reads a consistent list
        self._wake.trigger()  # rebuild the wait set now
        return subscription

    def start(self) -> None:
        """Start serving the subscriptions (idempotent)."""
        if not self._thread.is_alive() and not self._stop.is_set():
            self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop the thread (idempotent); safe to call from any thread, also after the context shut down."""
        self._stop.set()
        with suppress(Exception):  # a shut-down context: the thread notices within WAIT_TIMEOUT_NS
            self._wake.trigger()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout_s)

    def _run(self) -> None:
        context = self.node.context
        try:
            while not self._stop.is_set() and context.ok():
                self._serve(self._entries)
        except Exception as err:  # a context shut down under a wait is the owner's to report
            if context.ok() and not self._stop.is_set():
                self.error = err
                raise

    def _serve(self, entries: list[tuple[Subscription, Callable[[Any], None]]]) -> None:
        """Wait on ``entries`` with one wait set (built once, refilled per wait) until the list changes or a stop."""
        context = self.node.context
        with ExitStack() as stack:
            handles = [sub.handle for sub, _ in entries]
            for handle in handles:
                stack.enter_context(handle)  # keeps it alive while waited on (__enter__ returns None)
            stack.enter_context(self._wake.handle)
            stack.enter_context(context.handle)
            wait_set = _rclpy.WaitSet(len(handles), 1, 0, 0, 0, 0, context.handle)
            served = list(zip(handles, entries, strict=True))
            while entries is self._entries and not self._stop.is_set() and context.ok():
                wait_set.clear_entities()
                for handle in handles:
                    wait_set.add_subscription(handle)
                wait_set.add_guard_condition(self._wake.handle)
                wait_set.wait(WAIT_TIMEOUT_NS)
                ready = wait_set.get_ready_entities("subscription")
                for handle, (subscription, callback) in served:
                    if handle.pointer in ready:
                        taken = handle.take_message(subscription.msg_type, subscription.raw)
                        if taken is not None:
                            callback(taken[0])
