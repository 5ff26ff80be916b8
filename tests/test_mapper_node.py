"""The mapper node as a real process: round trip through a loopback, rejection, clamping, diagnostics."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import diagnostics_from_msg, joint_state_from_msg, joint_state_to_msg
from rh5_msgs_py.names import ACTUATOR_INDEX, ACTUATOR_NAMES, JOINT_INDEX, JOINT_NAMES

pytestmark = pytest.mark.ros


class Loopback:
    """The test's side of the wire: sends joint_commands, echoes actuator_commands as actuator_states."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import JointState

        self.node = node
        self.actuator_commands: list[Any] = []
        self.joint_states: list[Any] = []
        self.diagnostics: list[Any] = []
        self.echo = True
        self._commands = node.create_publisher(JointState, interfaces.JOINT_COMMANDS.name, interfaces.STREAM_QOS)
        self._states = node.create_publisher(JointState, interfaces.ACTUATOR_STATES.name, interfaces.STREAM_QOS)
        node.create_subscription(
            JointState, interfaces.ACTUATOR_COMMANDS.name, self._on_actuator_commands, interfaces.STREAM_QOS
        )
        node.create_subscription(
            JointState, interfaces.JOINT_STATES.name, self.joint_states.append, interfaces.STREAM_QOS
        )
        node.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, interfaces.EVENT_QOS)

    def _on_actuator_commands(self, msg: Any) -> None:
        self.actuator_commands.append(msg)
        if self.echo:
            self._states.publish(msg)

    def send_until(self, command: Any, done: Callable[[], bool], timeout_s: float = 10.0) -> bool:
        """Publish ``command`` every 20 ms until ``done()`` (best effort may drop the first ones)."""
        import rclpy

        deadline = time.monotonic() + timeout_s
        next_send = 0.0
        while time.monotonic() < deadline:
            if time.monotonic() >= next_send:
                self._commands.publish(command)
                next_send = time.monotonic() + 0.02
            rclpy.spin_once(self.node, timeout_sec=0.005)
            if done():
                return True
        return False

    def reset(self) -> None:
        self.actuator_commands.clear()
        self.joint_states.clear()

    def quiesce(self, quiet_s: float = 0.2, timeout_s: float = 5.0) -> None:
        """Stop echoing, wait until nothing has arrived for ``quiet_s`` (echoes of earlier tests), then reset."""
        import rclpy

        self.echo = False
        deadline = time.monotonic() + timeout_s
        quiet_since = time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - quiet_since < quiet_s:
            seen = len(self.actuator_commands) + len(self.joint_states)
            rclpy.spin_once(self.node, timeout_sec=0.01)
            if len(self.actuator_commands) + len(self.joint_states) != seen:
                quiet_since = time.monotonic()
        self.reset()


@pytest.fixture(scope="module")
def mapper_process(ros_graph: Any, ros_test_environment: dict[str, str]) -> Iterator[SuiteRun]:
    bringup = Bringup("", (NodeSpec("mapper", "rh5_hyrodyn_mapper", "mapper_node", {}),))
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "mapper_node"
    with SuiteRun(bringup, log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
        assert wait_for_nodes(ros_graph, {"mapper"}) == set()
        yield run


@pytest.fixture(scope="module")
def loopback(ros_graph: Any, mapper_process: SuiteRun) -> Loopback:
    return Loopback(ros_graph)


def _feasible_command(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = np.zeros(len(JOINT_NAMES))
    q[JOINT_INDEX["LLKnee"]] = q[JOINT_INDEX["LRKnee"]] = 0.6
    q[JOINT_INDEX["LLHip3"]] = q[JOINT_INDEX["LRHip3"]] = -0.3
    q += rng.uniform(-0.05, 0.05, q.shape)
    q[JOINT_INDEX["LLKnee"]] = abs(q[JOINT_INDEX["LLKnee"]])
    return (
        q,
        rng.uniform(-0.2, 0.2, q.shape),
        rng.uniform(-4.0, 4.0, q.shape),
    )  # inside every torque limit (head yaw 4.9 Nm)


def test_command_round_trip_through_the_node_is_exact(loopback: Loopback) -> None:
    """joint_commands -> actuator_commands -> (loopback) actuator_states -> joint_states, equal within 1e-9."""
    q, v, tau = _feasible_command(1)
    loopback.reset()
    command = joint_state_to_msg(JOINT_NAMES, q, v, tau, stamp_ns=123_456_789)
    assert loopback.send_until(command, lambda: bool(loopback.joint_states))
    expected = robot_mapper().to_actuators(q, v, tau=tau)
    l, ld, f = joint_state_from_msg(loopback.actuator_commands[0], ACTUATOR_NAMES)
    np.testing.assert_allclose(l, expected.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ld, expected.velocity, rtol=0, atol=1e-12)
    np.testing.assert_allclose(f, expected.effort, rtol=1e-12, atol=1e-9)
    back = loopback.joint_states[0]
    q2, v2, tau2 = joint_state_from_msg(back, JOINT_NAMES)
    np.testing.assert_allclose(q2, q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v2, v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tau2, tau, rtol=0, atol=1e-9)
    assert back.header.stamp.nanosec == 123_456_789


@pytest.mark.parametrize("defect", ["nan", "inf", "unknown_joint"])
def test_bad_commands_are_never_forwarded(loopback: Loopback, defect: str) -> None:
    q, v, tau = _feasible_command(2)
    names = list(JOINT_NAMES)
    if defect == "nan":
        v[3] = np.nan
    elif defect == "inf":
        q[20] = np.inf
    else:
        names[5] = "LLTail"
    loopback.reset()
    bad = joint_state_to_msg(names, q, v, tau)
    assert not loopback.send_until(bad, lambda: bool(loopback.actuator_commands), timeout_s=0.5)
    good = joint_state_to_msg(JOINT_NAMES, *_feasible_command(3))
    assert loopback.send_until(good, lambda: bool(loopback.actuator_commands))


def test_out_of_limit_command_is_clamped_and_reported(loopback: Loopback) -> None:
    mapper = robot_mapper()
    q, v, tau = _feasible_command(4)
    q[JOINT_INDEX["LLKnee"]] = 1.9  # far beyond the 88 deg ROM: the knee actuator would leave its stroke
    tau[JOINT_INDEX["LRKnee"]] = 5000.0  # beyond 5845 N at any moment arm below 85 mm
    loopback.reset()
    loopback.diagnostics.clear()
    assert loopback.send_until(joint_state_to_msg(JOINT_NAMES, q, v, tau), lambda: bool(loopback.actuator_commands))
    l, _, f = joint_state_from_msg(loopback.actuator_commands[0], ACTUATOR_NAMES)
    assert l[ACTUATOR_INDEX["LLKnee_Act1"]] == mapper.limits.length_max[ACTUATOR_INDEX["LLKnee_Act1"]]
    assert f[ACTUATOR_INDEX["LRKnee_Act1"]] == pytest.approx(mapper.limits.force_max[ACTUATOR_INDEX["LRKnee_Act1"]])

    def clamp_reported() -> bool:
        statuses = [s for msg in loopback.diagnostics for s in diagnostics_from_msg(msg) if s.name == "rh5/mapper"]
        return any("clamped.LLKnee_Act1" in s.values and "clamped.LRKnee_Act1" in s.values for s in statuses)

    assert loopback.send_until(joint_state_to_msg(JOINT_NAMES, q, v, tau), clamp_reported, timeout_s=5.0)


def test_unassemblable_actuator_states_are_rejected(loopback: Loopback, mapper_process: SuiteRun) -> None:
    """Lengths no ankle pose can produce give a logged rejection, never a joint_states message."""
    import rclpy
    from sensor_msgs.msg import JointState

    l = robot_mapper().to_actuators(np.zeros(len(JOINT_NAMES))).position
    l[ACTUATOR_INDEX["LLAnkle_Act1"]] += 0.2
    states = loopback.node.create_publisher(JointState, interfaces.ACTUATOR_STATES.name, interfaces.STREAM_QOS)
    loopback.quiesce()  # the echoes of the clamping test above may still be on the way
    end = time.monotonic() + 0.5
    while time.monotonic() < end:
        states.publish(joint_state_to_msg(ACTUATOR_NAMES, l))
        rclpy.spin_once(loopback.node, timeout_sec=0.02)
    assert loopback.joint_states == []
    loopback.node.destroy_publisher(states)
    loopback.echo = True
