"""What every node of the suite shares: spec'd parameters, counted topics, a clean SIGINT exit.

Each node prints one ``RH5_SUMMARY {json}`` line on stdout when it stops (what it saw and
sent), which the launcher collects; ``run_node`` turns SIGINT/SIGTERM into exit code 0
and a bad start-up (e.g. an invalid parameter) into exit code 2 with the reason.
"""

from __future__ import annotations

import faulthandler
import json
import signal
import sys
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError
from rclpy.clock import Clock, ClockType
from rclpy.executors import (
    ConditionReachedException,
    Executor,
    ExternalShutdownException,
    ShutdownException,
    TimeoutException,
)
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions, install_signal_handlers
from rclpy.subscription import Subscription
from rclpy.task import Future
from rclpy.timer import Timer

from rh5_msgs_py.interfaces import Topic, message_class
from rh5_msgs_py.parameters import declare_parameters, load_spec, parameter_values
from rh5_msgs_py.realtime import RTPRIO_FIX, DeadlineLoop, RealtimeGrant
from rh5_msgs_py.ros_env import apply_safe_defaults
from rh5_msgs_py.streams import StreamThread

Applier = Callable[[Any], Callable[[], None] | None]
"""Checks a new parameter value (ValueError: refused) and returns what applies it once accepted."""
SUMMARY_PREFIX = "RH5_SUMMARY "
EXIT_BAD_START = 2
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
STACKS_SIGNAL = signal.SIGUSR1
"""Makes a running node print every thread's Python stack on stderr and go on."""


class SuiteNode(Node):
    """Base node: declares the parameters of its spec file and counts what it receives and sends."""

    def __init__(self, node_name: str, spec_package: str, spec_resource: str, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.param_specs = load_spec(spec_package, spec_resource)
        declare_parameters(self, self.param_specs)
        self.seen: Counter[str] = Counter()
        self.sent: Counter[str] = Counter()
        self._streams: StreamThread | None = None
        self._steady_clock: Clock | None = None
        self.sim_time = bool(self.get_parameter("use_sim_time").value)
        """Whether the node runs on the simulation's clock (/clock): its messages are stamped in simulated time."""
        self.appliers: dict[str, Applier] | None = None
        self.status_gate: Callable[[], object] = lambda: None
        """Called before the node builds and publishes its /diagnostics status: a real-time loop of the process
        makes it wait for the loop's slack (a status is hundreds of microseconds of work under the interpreter
        lock)."""
        self.callback_gate: Callable[[], object] | None = None
        """Set by a process with a real-time loop: the executor calls it before every callback of the process
        (``GatedExecutor``)."""

    def apply_live(self, appliers: Mapping[str, Applier]) -> None:
        """Make every writable parameter take effect at run time, on the next cycle of whatever uses it.

        ``appliers[name](value)`` runs while ROS decides on a set (after the spec's checks): it raises
        ValueError to refuse the value with its reason, else returns what to do once the set is accepted (or
        None). Each writable parameter of the spec needs one (a parameter that is only read at start-up must be
        ``read_only`` in the spec); ``run_node`` refuses to start a node that leaves one out.
        """
        writable = {spec.name for spec in self.param_specs if not spec.read_only}
        if set(appliers) != writable:
            msg = (
                f"{self.get_name()}: writable parameters without an applier {sorted(writable - set(appliers))}, "
                f"appliers for no writable parameter {sorted(set(appliers) - writable)}"
            )
            raise RuntimeError(msg)
        self.appliers = dict(appliers)
        pending: list[Callable[[], None]] = []

        def check(parameters: list[Any]) -> SetParametersResult:
            pending.clear()
            for parameter in parameters:
                applier = self.appliers.get(parameter.name)
                if applier is None:
                    continue
                try:
                    action = applier(parameter.value)
                except ValueError as err:
                    pending.clear()
                    return SetParametersResult(successful=False, reason=f"{parameter.name}: {err}")
                if action is not None:
                    pending.append(action)
            return SetParametersResult(successful=True)

        def apply(_parameters: list[Any]) -> None:
            while pending:
                pending.pop(0)()

        self.add_on_set_parameters_callback(check)
        self.add_post_set_parameters_callback(apply)

    @property
    def params(self) -> dict[str, Any]:
        """Current values of this node's parameters."""
        return parameter_values(self, self.param_specs)

    def subscribe(
        self, topic: Topic, callback: Callable[[Any], None] | None = None, *, raw: bool = False
    ) -> Subscription:
        """Subscribe with the topic's contract type and QoS, counting every message."""

        def on_message(msg: Any) -> None:
            self.seen[topic.name] += 1
            if callback is not None:
                callback(msg)

        return self.create_subscription(message_class(topic.type), topic.name, on_message, topic.qos, raw=raw)

    def subscribe_stream(self, topic: Topic, callback: Callable[[Any], None]) -> Subscription:
        """Like ``subscribe`` for a 1 kHz stream: served by the node's `StreamThread`, not the executor, so
        ``callback`` runs in that thread and must only touch thread-safe state."""
        if self._streams is None:
            self._streams = StreamThread(self, name=f"{self.get_name()}-streams")
            self.context.on_shutdown(self._streams.stop)
            self._streams.start()

        def on_message(msg: Any) -> None:
            self.seen[topic.name] += 1
            callback(msg)

        return self._streams.subscribe(topic, on_message)

    def create_wall_timer(self, period_s: float, callback: Callable[[], None]) -> Timer:
        """A timer on the steady clock: reports and polling keep their wall-clock rate under ``use_sim_time``
        (on the node's clock a simulation at 0.08 x real time would make a 1 s report come every 12 s)."""
        if self._steady_clock is None:
            self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        return self.create_timer(period_s, callback, clock=self._steady_clock)

    def stamp_ns(self) -> int:
        """Now on the node's clock (the simulation's under ``use_sim_time``): the stamp of what it publishes."""
        return self.get_clock().now().nanoseconds

    def start_loop(self, rate_hz: float, step: Callable[[int, int], None], name: str, priority: int) -> DeadlineLoop:
        """Start the node's 1 kHz loop: SCHED_FIFO at ``priority`` if granted (the grant logged, a refusal warned
        about once), stopped when SIGINT shuts the context down (before the node is destroyed)."""
        loop = DeadlineLoop(
            rate_hz, step, name=name, priority=priority, on_realtime=lambda g: log_realtime_grant(self.get_logger(), g)
        )
        self.context.on_shutdown(loop.stop)
        loop.start()
        return loop

    def destroy_node(self) -> None:
        """Stop the stream thread before the subscriptions go away."""
        if self._streams is not None:
            self._streams.stop()
        super().destroy_node()

    def advertise(self, topic: Topic) -> Callable[[Any], None]:
        """Create a publisher with the topic's contract type and QoS; return a counting publish function."""
        publisher: Publisher = self.create_publisher(message_class(topic.type), topic.name, topic.qos)

        def publish(msg: Any) -> None:
            try:
                publisher.publish(msg)
            except RCLError:
                if self.context.ok():
                    raise
                return  # a loop thread publishing while SIGINT shuts the context down: the node is stopping
            self.sent[topic.name] += 1

        return publish

    def finish(self) -> None:
        """Stop producing (loops, helper processes) before the summaries are taken, so that they are final;
        idempotent. Nothing to stop by default."""

    def summary(self) -> dict[str, Any]:
        """What this node saw and sent, for the launcher's report."""
        return {"node": self.get_name(), "seen": dict(self.seen), "sent": dict(self.sent)}


_refusal_warned = False


def log_realtime_grant(logger: Any, grant: RealtimeGrant) -> None:
    """Log what a loop was granted: info when real-time, one warning per process naming the fix when refused."""
    global _refusal_warned  # noqa: PLW0603 (one warning per process, however many loops)
    if grant.granted or not grant.requested:
        logger.info(f"loop scheduling: {grant.describe()}")
    elif not _refusal_warned:
        _refusal_warned = True
        logger.warning(
            f"real-time scheduling refused: {grant.reason}. The 1 kHz loop runs at normal priority and will miss "
            f"deadlines under load. To fix, {RTPRIO_FIX}."
        )


class GatedExecutor(Executor):
    """A single-threaded executor that runs each ready callback only once ``gate`` returns.

    In a process with a real-time loop the gate waits for the loop's slack: Python runs one thread at a time,
    and a callback that holds the interpreter lock when the loop wakes delays that cycle by up to the lock's
    switch interval plus the callback's longest C call. Measured in the control process (make run): 594 deadline
    misses ungated, 405 gated; loading a 6300-point trajectory cost 136 misses ungated, 27 gated. Built on rclpy's
    custom-executor interface (``spin_once`` and ``spin_once_until_future_complete`` over
    ``wait_for_ready_callbacks``), as rclpy's own single-threaded executor is.
    """

    def __init__(self, gate: Callable[[], object]) -> None:
        super().__init__()
        self._gate = gate

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` for one ready callback; run it once the gate opens."""
        self._run_one(timeout_sec, lambda: False)

    def spin_once_until_future_complete(self, future: Future, timeout_sec: Any = None) -> None:
        """As ``spin_once``, and also return when ``future`` is done."""
        future.add_done_callback(lambda _future: self.wake())
        self._run_one(timeout_sec, future.done)

    def _run_one(self, timeout_sec: Any, wait_condition: Callable[[], bool]) -> None:
        try:
            handler, _, _ = self.wait_for_ready_callbacks(timeout_sec, None, wait_condition)
        except (ShutdownException, TimeoutException, ConditionReachedException):
            return
        self._gate()
        handler()
        if handler.exception() is not None:
            raise handler.exception()
        handler.result()


@contextmanager
def _stops_deferred() -> Iterator[Callable[[], bool]]:
    """While nodes are built, SIGINT and SIGTERM only note the stop (the caller ends once they exist).

    With rclpy's handlers installed, a stop shuts the context down under a half-built node: its next rcl call
    fails, and a stabilizer stopped while it created its services aborted (exit -6, a C++ thread never joined).
    """
    received: list[int] = []
    previous = {sig: signal.signal(sig, lambda number, _frame: received.append(number)) for sig in STOP_SIGNALS}
    try:
        yield lambda: bool(received)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def run_node(factory: Callable[[], SuiteNode | Sequence[SuiteNode]], args: list[str] | None = None) -> None:
    """Run one node, or the nodes of one process (``factory`` returns them all), until SIGINT/SIGTERM; exit 0
    when stopped, 2 when it could not start. Each node prints its summary line when it stops (the first node
    last: a process hosting several nodes lists its host node first).

    A stop that arrives while the nodes are being built takes effect once they exist: they stop at once, cleanly,
    with their summaries (the launcher and tests may signal a node as soon as it shows up in the graph).
    """
    apply_safe_defaults()
    faulthandler.register(STACKS_SIGNAL, all_threads=True)  # `kill -USR1 <pid>`: where a stuck node is, on stderr
    rclpy.init(args=args if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    nodes: list[SuiteNode] = []
    stopped = False
    try:
        with _stops_deferred() as stop_requested:
            built = factory()
        nodes = [built] if isinstance(built, SuiteNode) else list(built)
        if stop_requested():
            raise KeyboardInterrupt
        install_signal_handlers(SignalHandlerOptions.ALL)  # from here a stop wakes the executor, as rclpy.init's would
        for node in nodes:
            if node.appliers is None and any(not spec.read_only for spec in node.param_specs):
                msg = f"{node.get_name()}: writable parameters but no apply_live (a set would be ignored)"
                raise RuntimeError(msg)
        gate = next((node.callback_gate for node in nodes if node.callback_gate is not None), None)
        executor = rclpy.get_global_executor() if gate is None else GatedExecutor(gate)
        for node in nodes:
            executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        stopped = True
    except Exception as err:
        if rclpy.ok():
            if nodes:
                raise
            print(f"cannot start: {err}", file=sys.stderr, flush=True)
            rclpy.try_shutdown()
            sys.exit(EXIT_BAD_START)
        # SIGINT/SIGTERM shut the context down under work in flight (a message being taken, a node being built)
        print(f"ignored during shutdown: {err!r}", file=sys.stderr, flush=True)
        stopped = True
    finally:
        for node in nodes:
            node.finish()
        for node in reversed(nodes):
            print(SUMMARY_PREFIX + json.dumps(node.summary(), sort_keys=True), flush=True)
        for node in nodes:
            node.destroy_node()
        if not nodes and stopped:
            summary = {"node": None, "seen": {}, "sent": {}, "stopped": "during start-up"}
            print(SUMMARY_PREFIX + json.dumps(summary, sort_keys=True), flush=True)
        rclpy.try_shutdown()


def parse_summaries(output: str) -> list[dict[str, Any]]:
    """Every summary line in a process's captured stdout, in the order printed."""
    return [json.loads(line[len(SUMMARY_PREFIX) :]) for line in output.splitlines() if line.startswith(SUMMARY_PREFIX)]


def parse_summary(output: str) -> dict[str, Any] | None:
    """The last summary line in a process's captured stdout: its node's, or a composed process's host node's."""
    summaries = parse_summaries(output)
    return summaries[-1] if summaries else None
