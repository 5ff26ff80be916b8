"""The stabilizer node as a real process: services with reasons, 1 kHz joint_commands, estop, bad trajectories."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.orchestration.cli import call_trigger
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import diagnostics_from_msg, joint_state_to_msg, joint_trajectory_to_msg
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop

pytestmark = pytest.mark.ros


class Harness:
    """The test's side: publishes joint_states at 1 kHz, trajectories and the estop latch; counts commands."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Bool
        from trajectory_msgs.msg import JointTrajectory

        self.node = node
        self.commands: list[float] = []
        """Header stamps of the joint_commands received (s): when the stabilizer's cycle made them."""
        self.statuses: list[Any] = []
        self.trajectory = node.create_publisher(
            JointTrajectory, interfaces.PLANNED_TRAJECTORY.name, interfaces.LATCHED_QOS
        )
        self.estop = node.create_publisher(Bool, interfaces.DRIVER_ESTOP.name, interfaces.LATCHED_QOS)
        self._states = node.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
        node.create_subscription(
            JointState,
            interfaces.JOINT_COMMANDS.name,
            lambda m: self.commands.append(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec),
            interfaces.STREAM_QOS,
        )
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, interfaces.EVENT_QOS)
        self._pose = np.zeros(NUM_JOINTS)
        self.loop = DeadlineLoop(1000.0, self._publish_state, name="test-joint-states")

    def _publish_state(self, _now: int, _period: int) -> None:
        self._states.publish(joint_state_to_msg(JOINT_NAMES, self._pose, np.zeros(NUM_JOINTS)))

    def _on_diagnostics(self, msg: Any) -> None:
        self.statuses.extend(s for s in diagnostics_from_msg(msg) if s.name == "rh5/stabilizer")

    def spin_for(self, seconds: float) -> None:
        import rclpy

        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)


@pytest.fixture(scope="module")
def harness(ros_graph: Any, ros_test_environment: dict[str, str]) -> Iterator[Harness]:
    # The physics bringup's 0.5 s stale-state timeout: this test is about services and rate; the 5 ms rule has its
    # own unit test, and the test-side 1 kHz publisher shares two cores with everything else here (late in a CI
    # run a stall of it went past 50 ms, and the stabilizer rightly held before the test asked it to). Priority 50
    # as the control process has on the robot: with normal scheduling the loop lost up to 30 % of its cycles to
    # the test's own 1 kHz publisher and executor on these two cores.
    spec = NodeSpec(
        "stabilizer", "rh5_joint_stabilizer", "stabilizer_node", {"state_timeout_s": 0.5, "realtime_priority": 50}
    )
    bringup = Bringup("", (spec,))
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "stabilizer_node"
    test_side = Harness(ros_graph)
    test_side.loop.start()
    try:
        with SuiteRun(bringup, log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"stabilizer"}) == set()
            test_side.run = run
            yield test_side
    finally:
        test_side.loop.stop()
    assert run.processes[0].process.returncode == 0
    assert "Traceback" not in run.processes[0].stderr_path.read_text()


def _trajectory(names: list[str], seconds: float = 3.0) -> Any:
    t = np.arange(0.0, seconds, 0.01)
    q = 0.05 * np.sin(2 * np.pi * 0.5 * t)[:, None] * np.ones(len(names))
    return joint_trajectory_to_msg(names, t, q)


def test_start_without_trajectory_is_refused_with_the_reason(harness: Harness) -> None:
    ok, message = call_trigger(harness.node, "/stabilizer/start", timeout_s=1.0)
    assert not ok
    assert "no trajectory" in message


def test_bad_trajectory_is_not_loaded(harness: Harness) -> None:
    names = list(JOINT_NAMES)
    names[0] = "LLTail"
    harness.trajectory.publish(_trajectory(names))
    harness.spin_for(0.5)
    ok, message = call_trigger(harness.node, "/stabilizer/start", timeout_s=1.0)
    assert not ok
    assert "no trajectory" in message


def test_start_plays_at_1khz_then_hold_and_stop(harness: Harness) -> None:
    harness.trajectory.publish(_trajectory(list(JOINT_NAMES)))
    ok, message = call_trigger(harness.node, "/stabilizer/start")
    assert ok, message
    harness.commands.clear()
    seen = len(harness.statuses)
    harness.spin_for(1.5)
    # Best effort through DDS to this test's own Python executor on 2 busy cores: late in a CI run the test
    # received only every second or third sample (a spin takes the newest), so it checks that commands flow, and
    # the rate is the loop's own report.
    assert len(harness.commands) >= 100, f"{len(harness.commands)} joint_commands in 1.5 s"
    playing = [s for s in harness.statuses[seen:] if s.values.get("state") in ("ramp_in", "playing")]
    assert playing, "no diagnostics while playing"
    # The loop's median period is its rate; the rate over a window also counts the cycles the hypervisor takes
    # away from this VM (#13: 1-3 % even for a bare loop here), so it only has to rule out a slower loop.
    periods = [float(s.values[interfaces.LoopKeys.PERIOD_P50_US]) for s in playing]
    rates = [float(s.values[interfaces.LoopKeys.RATE_HZ]) for s in playing]
    assert all(950.0 < p < 1050.0 for p in periods), f"median periods while playing: {periods} us"
    assert min(rates) > 800.0, f"loop rates while playing: {rates} Hz"
    ok, message = call_trigger(harness.node, "/stabilizer/hold", timeout_s=2.0)
    assert (ok, message) == (True, "holding")
    harness.spin_for(1.2)
    assert any(s.values.get("state") == "holding" for s in harness.statuses[-2:])
    assert "loop.rate_hz" in harness.statuses[-1].values
    ok, message = call_trigger(harness.node, "/stabilizer/stop", timeout_s=2.0)
    assert (ok, message) == (True, "stopping")
    harness.spin_for(0.2)
    harness.commands.clear()
    harness.spin_for(0.3)
    assert harness.commands == []


def test_estop_latch_refuses_start(harness: Harness) -> None:
    from std_msgs.msg import Bool

    harness.estop.publish(Bool(data=True))
    harness.spin_for(0.3)
    ok, message = call_trigger(harness.node, "/stabilizer/start", timeout_s=1.0)
    assert not ok
    assert "emergency stop" in message
    harness.estop.publish(Bool(data=False))
    harness.spin_for(0.3)


def test_trajectory_file_parameter_loads_and_plays(
    harness: Harness, ros_test_environment: dict[str, str], write_joint_trajectory: Callable[..., Path]
) -> None:
    """A second stabilizer started with trajectory_file plays it (no planned_trajectory needed)."""
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "stabilizer_file"
    path = write_joint_trajectory(log_dir.parent / "test_sine.rh5traj", 2.0, amplitude=0.05)
    spec = NodeSpec(
        "stabilizer_file",
        "rh5_joint_stabilizer",
        "stabilizer_node",
        {"state_timeout_s": 0.05, "trajectory_file": str(path)},
    )
    with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
        assert wait_for_nodes(harness.node, {"stabilizer_file"}) == set()
        ok, message = call_trigger(harness.node, "/stabilizer_file/start")
    assert ok, message
    assert "trajectory loaded: 67 points" in run.processes[0].stderr_path.read_text()
