"""The hardware layer at 1 kHz over real UDP on 127.0.0.1: the driver against the simulated-hardware node.

First the driver's cycle (DriverCore in this process, on its own deadline loop) against the
sim_hardware node in its own process, one test per safety rule with its timing; then both
nodes as processes, driven through their ROS interface.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.hardware.driver_node import actuator_limits
from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.hardware.rig import LINEAR, SINE_AMPLITUDE, DriverLoop, sine_centre
from rh5_bringup.hardware.transports import open_transport
from rh5_bringup.orchestration.cli import call_trigger
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import diagnostics_from_msg, joint_state_from_msg, joint_state_to_msg
from rh5_msgs_py.names import ACTUATOR_INDEX, ACTUATOR_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop

pytestmark = pytest.mark.ros

LIMITS = actuator_limits()
CENTRE = sine_centre(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position, LIMITS)


def set_parameters(node: Any, target: str, **values: Any) -> None:
    """Set parameters of another node through its SetParameters service."""
    import rclpy
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    client = node.create_client(SetParameters, f"/{target}/set_parameters")
    assert client.wait_for_service(timeout_sec=10.0)
    params = [
        Parameter(k, Parameter.Type.STRING_ARRAY, v) if isinstance(v, list) else Parameter(k, value=v)
        for k, v in values.items()
    ]
    request = SetParameters.Request(parameters=[p.to_parameter_msg() for p in params])
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
    assert all(r.successful for r in future.result().results), future.result().results
    node.destroy_client(client)


@pytest.fixture(scope="module")
def boards(
    ros_graph: Any, ros_test_environment: dict[str, str], free_udp_port: Callable[[], int]
) -> Iterator[tuple[int, SuiteRun]]:
    """The sim_hardware node listening on a free UDP port."""
    port = free_udp_port()
    spec = NodeSpec("sim_hardware", "rh5_bringup", "sim_hardware_node", {"listen_port": port})
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "driver_sim"
    with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
        assert wait_for_nodes(ros_graph, {"sim_hardware"}) == set()
        yield port, run
    assert run.processes[0].process.returncode == 0
    summary = run.processes[0].summary()
    assert summary["counts"].get("bad_commands", 0) == 0  # nothing unencodable ever reached the boards


SILENCE_TIMEOUT_NS = 5_000_000  # the rule's value on the robot


@pytest.fixture
def driver(request: pytest.FixtureRequest, boards: tuple[int, SuiteRun]) -> Iterator[DriverLoop]:
    """A driver cycle at 1 kHz against the boards, enabled and commanding the sine.

    Only the silence test keeps the 5 ms silence rule: this 2-core virtual machine deschedules the
    emulator process for a few ms now and then, which is a silence the rule rightly acts on, and
    would end the other tests for a reason that is not theirs. They get 0.5 s, as the simulated
    bringup's physics mode does: a loaded CI machine once paused the emulator for over 50 ms.
    """
    port, _ = boards
    board_map = load_board_map()
    link = open_transport("udp", local=("127.0.0.1", 0), remote=("127.0.0.1", port), receivers=[board_map.pc_address])
    silence = SILENCE_TIMEOUT_NS if "silent_board" in request.node.name else 100 * SILENCE_TIMEOUT_NS
    rig = DriverLoop(board_map, link, LIMITS, CENTRE, silence_timeout_ns=silence)
    rig.loop.start()
    time.sleep(0.05)  # the boards learn where the driver is
    assert rig.core.enable(True)[0]
    try:
        yield rig
    finally:
        rig.loop.stop()
        link.shutdown()


def test_sine_on_every_actuator_is_tracked(driver: DriverLoop) -> None:
    """Bound: with velocity feed-forward the boards' cascade follows the 0.5 Hz sine within microns
    (sim/actuators tests); the reading is one to two cycles old (A w 2 ms = 31 um at 5 mm): 1 mm and
    10 mrad on 99 % of the cycles. The rest are this 2-core machine descheduling the emulator process
    for a while (the reference runs on meanwhile), which says nothing about the driver."""
    time.sleep(3.0)
    errors = driver.tracking_error(percentile=99.0)
    context = (driver.core.safe_hold_reason, dict(driver.core.counts), driver.events, driver.loop.stats())
    assert errors[LINEAR].max() < 1e-3, context
    assert errors[~LINEAR].max() < 10e-3, dict(zip(ACTUATOR_NAMES, errors.round(6), strict=True))
    assert not driver.core.safe_hold_reason
    assert 0 < driver.core.latency.percentiles_us()["p50_us"] < 5000.0  # echoes seen (bench/driver.py: the p99)


def test_a_silent_board_puts_the_robot_in_safe_hold_within_5_ms(driver: DriverLoop, ros_graph: Any) -> None:
    knee = ACTUATOR_INDEX["LLKnee_Act1"]
    for _ in range(3):  # a stall of the emulator process (every board silent at once) may pre-empt the knee's rule
        time.sleep(0.3)
        driver.events.clear()
        assert driver.core.enable(True)[0]  # clears a safe hold a stall of the emulator may have caused so far
        try:
            set_parameters(ros_graph, "sim_hardware", silent_boards=["LLKnee_Act1"])
            time.sleep(0.3)
            last_heard = int(driver.core.heard_ns[knee])
            ok, reason = driver.core.enable(True)
        finally:
            set_parameters(ros_graph, "sim_hardware", silent_boards=[])
        if not any(at <= last_heard for at, _ in driver.events):  # no hold before the knee went silent
            break
    events = [(at, text) for at, text in driver.events if at > last_heard]
    assert events, "no safe-hold event"
    event_at = events[0][0]
    assert "LLKnee_Act1" in events[0][1]
    assert event_at - last_heard > SILENCE_TIMEOUT_NS
    # The rule needs 5 ms and 5 of our own cycles (a stalled driver must not blame the boards), so the hold
    # must come in the first cycle that met both: no earlier cycle after the last answer may have met them.
    t, _, _ = driver.history()
    cycles = t[(t > last_heard) & (t < event_at)]  # the cycles after the last answer, up to the detecting one
    assert len(cycles) > driver.core.silence_cycles
    overdue = (np.arange(1, len(cycles)) > driver.core.silence_cycles) & (cycles[:-1] - last_heard > SILENCE_TIMEOUT_NS)
    assert not overdue.any(), f"the hold came {int(overdue.sum())} cycles late"
    assert driver.core.mode == CommandMode.HOLD
    assert not ok
    assert "LLKnee_Act1" in reason


def test_stale_commands_make_the_boards_hold(driver: DriverLoop) -> None:
    time.sleep(0.5)
    driver.commanding = False
    stopped_at = time.monotonic_ns()
    time.sleep(0.4)  # long enough for 100 cycles after the timeout even when a loaded machine halves the rate
    t, _, measured = driver.history()
    assert driver.core.mode == CommandMode.HOLD
    due = int(np.sum(t > stopped_at + 21_000_000))  # cycles after the 20 ms command timeout (and one cycle)
    assert driver.core.counts["stale_command_cycles"] >= due > 100
    holding = measured[t > stopped_at + 40_000_000]
    assert np.abs(holding - holding[0]).max() < 2e-4  # the boards hold where they were


def test_estop_holds_and_latches_until_reset(driver: DriverLoop) -> None:
    time.sleep(0.3)
    driver.core.estop()
    time.sleep(0.05)
    assert driver.core.mode == CommandMode.HOLD
    assert driver.core.enable(True) == (False, "refused: emergency stop is latched (call ~/reset_estop)")
    driver.core.reset_estop()
    assert driver.core.enable(True)[0]
    time.sleep(0.05)
    assert driver.core.mode == CommandMode.POSITION_FF


def test_setpoints_beyond_the_stroke_are_clamped_and_counted(driver: DriverLoop) -> None:
    knee = ACTUATOR_INDEX["LRKnee_Act1"]
    driver.offset[knee] = 0.5  # far beyond the 391 mm stroke end
    started = time.monotonic_ns()
    time.sleep(1.5)
    t, _, measured = driver.history()
    limit = LIMITS.length_max[knee]
    assert measured[:, knee].max() <= limit + 1e-6
    assert measured[-1, knee] == pytest.approx(limit, abs=1e-3)
    assert driver.core.clamped["LRKnee_Act1"] >= int(np.sum(t > started + 2_000_000))  # every cycle since
    driver.offset[knee] = 0.0


def test_lost_and_corrupted_telemetry_is_counted_not_fatal(driver: DriverLoop, ros_graph: Any) -> None:
    try:
        set_parameters(ros_graph, "sim_hardware", drop_rate=0.01, corrupt_crc_rate=0.01)
        time.sleep(1.0)
    finally:
        set_parameters(ros_graph, "sim_hardware", drop_rate=0.0, corrupt_crc_rate=0.0)
    stats = driver.core.transport.stats().decoder
    assert sum(s.crc_errors for s in stats.senders.values()) > 100  # ~320 expected in 1 s
    assert sum(s.lost for s in stats.senders.values()) > 100  # dropped frames show as counter gaps


class CommandSource:
    """Publishes a sine on actuator_commands at 1 kHz and records actuator_states, as the mapper would."""

    def __init__(self, node: Any) -> None:
        from sensor_msgs.msg import JointState

        self.node = node
        self.states: list[tuple[int, np.ndarray]] = []
        self.bad = False
        self.bad_published = 0
        self._t0 = time.monotonic_ns()
        self._wall_minus_monotonic = time.time_ns() - self._t0
        self._publisher = node.create_publisher(JointState, interfaces.ACTUATOR_COMMANDS.name, interfaces.STREAM_QOS)
        self._subscription = node.create_subscription(
            JointState, interfaces.ACTUATOR_STATES.name, self._on_states, interfaces.STREAM_QOS
        )
        self.loop = DeadlineLoop(1000.0, self._publish, "test-commands")

    def close(self) -> None:
        """Stop publishing and leave the session's shared observer node as it was (later tests reuse it)."""
        self.loop.stop()
        self.node.destroy_subscription(self._subscription)
        self.node.destroy_publisher(self._publisher)

    def reference(self, now_ns: int) -> tuple[np.ndarray, np.ndarray]:
        w, t = np.pi, (now_ns - self._t0) / 1e9
        return CENTRE + SINE_AMPLITUDE * np.sin(w * t), SINE_AMPLITUDE * w * np.cos(w * t)

    def _publish(self, now_ns: int, _period: int) -> None:
        position, velocity = self.reference(now_ns)
        if self.bad:
            position = position.copy()
            position[4] = np.nan
            self.bad_published += 1
        self._publisher.publish(joint_state_to_msg(ACTUATOR_NAMES, position, velocity, np.zeros(len(position))))

    def _on_states(self, msg: Any) -> None:
        """Keep each reading at the time the driver stamped it (wall clock, moved onto the monotonic clock of the
        reference): when this busy process takes messages late, receive times would show its lag as an error."""
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        self.states.append((stamp_ns - self._wall_minus_monotonic, joint_state_from_msg(msg, ACTUATOR_NAMES).position))

    def spin_for(self, seconds: float) -> None:
        import rclpy

        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def publish_bad(self, count: int, timeout_s: float) -> None:
        """Publish NaN commands until `count` went out (or the timeout): late in a full run this busy process's
        1 kHz loop falls behind, so a fixed time would send a varying number (CI: 0.3 s gave 45 rejections)."""
        self.bad = True
        end = time.monotonic() + timeout_s
        while self.bad_published < count and time.monotonic() < end:
            self.spin_for(0.01)
        self.bad = False


def test_driver_node_and_sim_node_through_ros(
    boards: tuple[int, SuiteRun], ros_graph: Any, ros_test_environment: dict[str, str]
) -> None:
    """actuator_commands -> driver node -> UDP -> sim node -> UDP -> driver node -> actuator_states."""
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import Bool
    from std_srvs.srv import SetBool

    port, _ = boards
    statuses: list[Any] = []
    latch: list[bool] = []
    subscriptions = [
        ros_graph.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            lambda m: statuses.extend(s for s in diagnostics_from_msg(m) if s.name == "rh5/driver"),
            interfaces.EVENT_QOS,
        ),
        ros_graph.create_subscription(
            Bool, interfaces.DRIVER_ESTOP.name, lambda m: latch.append(m.data), interfaces.LATCHED_QOS
        ),
    ]
    source = CommandSource(ros_graph)
    # 0.5 s silence timeout, as the physics bringup has: the 5 ms rule has its timing test above; here the boards
    # share two cores with this process's 1 kHz publisher, and a stall of the emulator late in a full run latched a
    # 50 ms rule's safe hold (CI: every reading 5 mm off its sine). The silent board below stays silent for 1.3 s.
    spec = NodeSpec("driver", "rh5_bringup", "driver_node", {"router_port": port, "board_silence_timeout_s": 0.5})
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "driver_node"
    source.loop.start()
    try:
        with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"driver"}) == set()
            client = ros_graph.create_client(SetBool, "/driver/enable")
            assert client.wait_for_service(timeout_sec=10.0)
            import rclpy

            future = client.call_async(SetBool.Request(data=True))
            rclpy.spin_until_future_complete(ros_graph, future, timeout_sec=10.0)
            assert future.result().success, future.result().message
            source.states.clear()
            source.spin_for(2.5)
            times = np.array([t for t, _ in source.states])
            states = np.array([s for _, s in source.states])
            source.publish_bad(300, timeout_s=3.0)
            set_parameters(ros_graph, "sim_hardware", silent_boards=["LLKnee_Act1"])
            source.spin_for(1.3)
            set_parameters(ros_graph, "sim_hardware", silent_boards=[])
            ok, message = call_trigger(ros_graph, "/driver/estop")
            source.spin_for(1.3)
    finally:
        source.close()
        for subscription in subscriptions:
            ros_graph.destroy_subscription(subscription)
    summary = run.processes[0].summary()
    assert run.processes[0].process.returncode == 0
    assert (ok, message) == (True, "emergency stop latched; boards hold")
    assert latch[-1] is True
    # This process both publishes at 1 kHz and spins: it takes what it can; the node itself published every cycle
    # once every board had answered (before that it publishes nothing: a loaded start-up took 200 ms of 4 s, CI).
    assert len(states) > 500, f"{len(states)} actuator_states in 2.5 s"
    counts = summary["counts"]
    published = counts["cycles"] - counts.get("cycles_before_all_heard", 0)
    assert published > 0.8 * summary["loop"]["cycles"], counts
    assert abs(summary["sent"]["actuator_states"] - published) <= 2, (summary["sent"], counts)
    late = times > times[0] + 1e9
    references = np.array([source.reference(t)[0] for t in times[late]])
    typical, most = np.percentile(np.abs(states[late] - references), [50.0, 90.0], axis=0)
    # The reading, at the driver's stamp, is a DDS hop plus a board cycle old (a few ms: A w 5 ms = 80 um at
    # 5 mm): the median sample within 1 mm. This test process publishes the 1 kHz commands itself, and late in a
    # full run it stalls for tenths of a second (the driver then holds, CI measured 3.7-6.3 mm at the 90th
    # percentile): 90 % of the samples only within the sine's own swing, 2 A.
    assert typical[LINEAR].max() < 1e-3, (typical, summary["counts"])
    assert most[LINEAR].max() < 2 * SINE_AMPLITUDE[LINEAR].max(), (most, summary["counts"])
    # 300 NaN commands over a best-effort, keep-last-1 stream: the driver takes the newest of each burst (121 taken
    # here alone), and every one it took it rejected: none reached a board.
    assert source.bad_published >= 300, source.bad_published
    assert summary["counts"]["rejected_commands"] >= 50, (summary["counts"], source.bad_published)
    assert any(s.level == 2 and "LLKnee_Act1" in s.message for s in statuses)  # the silent board: an ERROR
    assert any(s.values.get("estopped") == "True" for s in statuses)
