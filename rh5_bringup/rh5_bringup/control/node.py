"""The control process: the driver, mapper and stabilizer nodes in one process, run by one real-time cycle.

As ros2_control's controller manager does, the ``control`` node owns a single 1 kHz loop
(rh5_bringup.control.cycle: read telemetry -> map -> stabilise -> map with the limits -> write
commands) under SCHED_FIFO, and hosts the ``driver``, ``mapper`` and ``stabilizer`` nodes with their
own names, parameters, services and diagnostics. The four 1 kHz topics (``actuator_states``,
``joint_states``, ``joint_commands``, ``actuator_commands``) keep their names, types and rates: the cycle
hands each cycle's data to a publishing child process (rh5_bringup.control.stream_publisher), so publishing
never takes the interpreter lock from the cycle, and a sample is dropped rather than the cycle delayed.
The executor thread and the thread that publishes a stabilizer state change run at SCHED_FIFO just below
the cycle (see ``__init__``). ``/diagnostics`` status ``rh5/control``: loop timing, the real-time grant,
telemetry-to-command latency, cycle duration (wall and CPU, per step) and the streams' counts.

    ros2 run rh5_bringup control_node --ros-args --params-file control.yaml   # (rh5 up starts it)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Final

from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.time import Time

from rh5_bringup.control.cycle import ControlCycle, CycleSample
from rh5_bringup.control.stream_publisher import STREAMS, StreamPublisherProcess
from rh5_bringup.hardware.driver_node import DriverNode
from rh5_hyrodyn_mapper.mapper_node import MapperNode
from rh5_joint_stabilizer.stabilizer_node import StabilizerNode
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import Level, Status, diagnostics_to_msg
from rh5_msgs_py.diagnostic_keys import CONTROL_STATUS, HARDWARE_ID, ControlKeys
from rh5_msgs_py.diagnostic_tasks import Increases, task_status
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import RealtimePublisher, pin_process, request_realtime

DIAGNOSTICS_PERIOD_S: Final = 1.0
HELPER_PRIORITY_BELOW: Final = 10
"""The status publisher and executor threads run this far below the cycle's SCHED_FIFO priority."""
STATUS_SLACK_NS: Final = 300_000
"""The same for a node's /diagnostics status (up to a hundred key-values)."""
CALLBACK_SLACK_NS: Final = 200_000
"""The executor starts a callback (a /clock tick, a service call, a parameter set) only this long before the cycle's
next wake-up or earlier."""


class BoardTimeClocks:
    """Under use_sim_time the control process's ROS clocks follow the simulated boards' clock, not /clock.

    The boards count the simulation's time as /clock does (the time each sample was measured), and the cycle
    stamps its streams with it already. Each node's /clock subscription is dropped: with four nodes in the process,
    every /clock message woke the executor four times, and each wake-up costs ~1.5 ms of interpreter time (the
    wait set holds every node's services), ~150 ms/s held from the cycle's interpreter lock in a 5 kg walk.
    """

    def __init__(self, nodes: Sequence[Node]) -> None:
        for node in nodes:
            for subscription in [s for s in node.subscriptions if s.topic_name == interfaces.CLOCK.name]:
                node.destroy_subscription(subscription)
        self._clocks = [node.get_clock() for node in nodes]
        self._last_ns = -1

    def follow(self, board_ns: int) -> None:
        """Set every clock to the boards' newest time (a no-op while it has not moved)."""
        if board_ns == self._last_ns:
            return
        self._last_ns = board_ns
        now = Time(nanoseconds=board_ns, clock_type=ClockType.ROS_TIME)
        for clock in self._clocks:
            clock.set_ros_time_override(now)


class ControlNode(SuiteNode):
    """Owns the control cycle over the hosted driver, mapper and stabilizer nodes."""

    def __init__(self, driver: DriverNode, mapper: MapperNode, stabilizer: StabilizerNode) -> None:
        super().__init__(interfaces.CONTROL_NODE, "rh5_bringup", "params/control.yaml")
        self.driver, self.mapper, self.stabilizer = driver, mapper, stabilizer
        self.streams = StreamPublisherProcess(self.get_namespace())
        self._streams_closed = False
        self._increases = Increases()
        self._hosts = {
            topic.name: host for topic, host in zip(STREAMS, (driver, mapper, stabilizer, mapper), strict=True)
        }
        self.publisher: RealtimePublisher[CycleSample] = RealtimePublisher(self._publish, name="control-publisher")
        self.board_clocks = BoardTimeClocks((self, driver, mapper, stabilizer)) if self.sim_time else None
        self.cycle = ControlCycle(
            driver.core,
            mapper.core,
            stabilizer.step,
            estop_to_stabilizer=stabilizer.core.set_estop,
            state_changed=lambda: stabilizer.state_changed,
            hand_off=self._hand_off,
            stamp=lambda: driver.core.stamp_ns(self.sim_time),
            board_time=None if self.board_clocks is None else self.board_clocks.follow,
        )
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        # One timer for the statuses of all four nodes: each executor wake-up rebuilds the wait set of every hosted
        # node (~1.5 ms of interpreter time, at any point of the cycle); the process wakes once a second, not 4 times.
        self.create_wall_timer(DIAGNOSTICS_PERIOD_S, self._publish_statuses)
        params = self.params
        for node in (self, driver, mapper, stabilizer):
            node.status_gate = self._wait_for_status_slack
        self.callback_gate = self._wait_for_callback_slack
        # The status publisher and the executor share the interpreter lock with the cycle. At normal priority the OS may
        # preempt them while they hold it (the simulation is busy on both cores), and the cycle then waits for
        # milliseconds: a priority inversion. They get SCHED_FIFO just below the cycle; they never spin, and
        # take from the other processes only the work they have (the publisher keeps to the cycle's slack).
        helper_priority = (
            max(params["realtime_priority"] - HELPER_PRIORITY_BELOW, 1) if params["realtime_priority"] else 0
        )
        self.publisher.on_start = lambda: request_realtime(helper_priority)
        self.helper_realtime = request_realtime(helper_priority)  # this thread: the executor's
        if params["cpu_affinity"]:  # after the stream publisher started: that child runs on any CPU
            self.get_logger().info(f"control process on CPUs {pin_process(params['cpu_affinity'])}")
        if not self.streams.wait_ready():
            self.get_logger().error(
                "the stream publisher process did not start: actuator_states, joint_states, joint_commands and "
                f"actuator_commands are not published (exit {self.streams.process.poll()}; see this log above)"
            )
        self.loop = self.start_loop(params["rate_hz"], self.cycle.step, "control-1kHz", params["realtime_priority"])
        self.publisher.start()  # after the loop exists: it waits for the loop's slack

    def _wait_for_status_slack(self) -> None:
        self.loop.wait_for_slack(STATUS_SLACK_NS)

    def _wait_for_callback_slack(self) -> None:
        self.loop.wait_for_slack(CALLBACK_SLACK_NS)

    def _hand_off(self, sample: CycleSample) -> None:
        """The cycle's hand-over (never blocks): the streams to the publishing process, a stabilizer state change
        to the status thread."""
        self.streams.send(
            sample.stamp_ns,
            (sample.actuator_states, sample.joint_states, sample.joint_commands, sample.actuator_commands),
        )
        if sample.stabilizer_state_changed:
            self.publisher.try_publish(sample)

    def _publish(self, _sample: CycleSample) -> None:
        """The status thread: the stabilizer's new state (it waits for the cycle's slack itself: status_gate)."""
        self.stabilizer.publish_status()

    def diagnostics(self) -> dict[str, object]:
        """The cycle's timing, real-time grant, latency and publisher counts (the ``rh5/control`` values)."""
        values = self.loop.diagnostics()
        values[ControlKeys.HELPERS_REALTIME] = self.helper_realtime.describe()
        cycle = self.cycle
        latency = cycle.telemetry_to_command.percentiles_us()
        values.update({ControlKeys.telemetry_to_command(k): round(v, 1) for k, v in latency.items()})
        values.update({ControlKeys.cycle(k): round(v, 1) for k, v in cycle.compute.percentiles_us().items()})
        values.update({ControlKeys.cycle(k, "cpu"): round(v, 1) for k, v in cycle.cpu.percentiles_us().items()})
        for stage, window in cycle.stages.items():
            values.update({ControlKeys.cycle(k, stage): round(v, 1) for k, v in window.percentiles_us().items()})
        values.update(self.streams.diagnostics())
        values.update({f"status_{k}": v for k, v in self.publisher.diagnostics().items()})
        return values

    def _publish_statuses(self) -> None:
        """Every node's /diagnostics status, each built in the cycle's slack (``status_gate``)."""
        for node in (self.driver, self.mapper, self.stabilizer):
            node.publish_status()
        self.publish_status()

    def publish_status(self) -> None:
        """The ``rh5/control`` status and its per-task statuses."""
        self.status_gate()
        values = self.diagnostics()
        if self.loop.error is not None:
            level, message = Level.ERROR, f"control cycle died: {self.loop.error!r}"
        elif self.loop.realtime is not None and self.loop.realtime.requested and not self.loop.realtime.granted:
            level, message = Level.WARN, f"running without real-time scheduling: {self.loop.realtime.reason}"
        else:
            level, message = Level.OK, "running"
        status = Status(CONTROL_STATUS, level, message, values, hardware_id=HARDWARE_ID)
        statuses = [status, *self.task_statuses()]
        self._publish_diagnostics(diagnostics_to_msg(statuses, stamp_ns=self.stamp_ns()))

    def task_statuses(self) -> list[Status]:
        """``control: loop`` (ERROR: the cycle died; WARN: deadline misses since the last report) and ``control:
        streams`` (WARN: samples dropped or the publishing process gone), in diagnostic_updater's layout."""
        grew, stats = self._increases, self.loop.stats()
        misses = grew("loop.misses", stats.deadline_misses)
        if self.loop.error is not None:
            loop = task_status("control", "loop", Level.ERROR, "the cycle died", {"error": repr(self.loop.error)})
        else:
            level, text = (Level.WARN, "deadline misses") if misses > 0 else (Level.OK, "on time")
            values = {"new_deadline_misses": int(misses), "rate_hz": stats.rate_hz}
            loop = task_status("control", "loop", level, text, values)
        dropped = grew("streams.dropped", self.streams.dropped)
        if not self.streams.alive:
            streams = task_status("control", "streams", Level.WARN, "publishing process gone: no 1 kHz topics")
        else:
            level, text = (Level.WARN, "samples dropped") if dropped > 0 else (Level.OK, "publishing")
            streams = task_status("control", "streams", level, text, {"new_dropped": int(dropped)})
        return [loop, streams]

    def summary(self) -> dict[str, Any]:
        """Adds the loop timing, latency and publisher counts to the base summary."""
        return {**super().summary(), "control": self.diagnostics()}

    def finish(self) -> None:
        """Stop the cycle, then the publishers; the streams' final counts go to their nodes' summaries."""
        self.loop.stop()
        self.publisher.stop()
        if not self._streams_closed:  # once: the counts go to the summaries once
            self._streams_closed = True
            for name, count in self.streams.close().items():
                self._hosts[name].sent[name] += count

    def destroy_node(self) -> None:
        """Stop everything (``finish``), then the node."""
        self.finish()
        super().destroy_node()


def control_process() -> list[SuiteNode]:
    """The nodes of the control process, the control node first (it starts the cycle once the others exist)."""
    driver = DriverNode(composed=True)
    mapper = MapperNode(composed=True)
    stabilizer = StabilizerNode(composed=True)
    return [ControlNode(driver, mapper, stabilizer), driver, mapper, stabilizer]


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup control_node``."""
    run_node(control_process, args)
