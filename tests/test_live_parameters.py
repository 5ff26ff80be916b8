"""Parameters mean what they say at run time: a writable parameter set on a running node changes what the node
does from its next cycle on, and a value the node cannot use is refused with the reason (never accepted and
then ignored). Real node processes, driven through their ROS parameter services."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.orchestration.cli import call_set_bool
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import diagnostics_from_msg, joint_state_to_msg
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_INDEX, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop

pytestmark = pytest.mark.ros

STANDING = robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position


def _set(node: Any, target: str, **values: Any) -> list[tuple[bool, str]]:
    """Set parameters of ``target`` through its service; (successful, reason) per parameter."""
    import rclpy
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    client = node.create_client(SetParameters, f"/{target}/set_parameters")
    try:
        assert client.wait_for_service(timeout_sec=10.0)
        params = [
            Parameter(k, Parameter.Type.STRING_ARRAY, v) if isinstance(v, list) else Parameter(k, value=v)
            for k, v in values.items()
        ]
        future = client.call_async(SetParameters.Request(parameters=[p.to_parameter_msg() for p in params]))
        rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
        return [(r.successful, r.reason) for r in future.result().results]
    finally:
        node.destroy_client(client)


class Observer:
    """Publishes a stream at a fixed rate from this process and keeps the latest /diagnostics of every node."""

    def __init__(self, node: Any, topic: Any, rate_hz: float, positions: list[np.ndarray]) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from sensor_msgs.msg import JointState

        self.node = node
        self.status: dict[str, dict[str, str]] = {}
        self._positions, self._k = positions, 0
        self._publisher = node.create_publisher(JointState, topic.name, interfaces.STREAM_QOS)
        self._subscription = node.create_subscription(
            DiagnosticArray, "/diagnostics", self._on_diagnostics, interfaces.EVENT_QOS
        )
        self.loop = DeadlineLoop(rate_hz, self._publish, "test-stream")
        self.loop.start()

    def _publish(self, _now: int, _period: int) -> None:
        position = self._positions[self._k % len(self._positions)]
        self._k += 1
        zeros = np.zeros(len(position))
        self._publisher.publish(joint_state_to_msg(ACTUATOR_NAMES, position, zeros, zeros))

    def _on_diagnostics(self, msg: Any) -> None:
        for status in diagnostics_from_msg(msg):
            self.status[status.name] = dict(status.values)

    def count(self, status: str, key: str) -> int:
        return int(self.status.get(status, {}).get(key, 0))

    def growth(self, status: str, key: str, seconds: float = 2.2) -> int:
        """How much a counter of ``status`` grew over ``seconds`` (diagnostics come at 1 Hz)."""
        self.spin_for(1.1)
        before = self.count(status, key)
        self.spin_for(seconds)
        return self.count(status, key) - before

    def spin_for(self, seconds: float) -> None:
        import rclpy

        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def close(self) -> None:
        self.loop.stop()
        self.node.destroy_subscription(self._subscription)
        self.node.destroy_publisher(self._publisher)


@pytest.fixture
def log_dir(ros_test_environment: dict[str, str], request: pytest.FixtureRequest) -> Path:
    return Path(ros_test_environment["ROS_LOG_DIR"]) / request.node.name


@pytest.fixture
def driver_and_boards(
    ros_graph: Any, boards_and_driver: Callable[..., AbstractContextManager[Any]], request: pytest.FixtureRequest
) -> Iterator[tuple[SuiteRun, Observer]]:
    """sim_hardware and the driver (command timeout 1 s), actuator_commands at 20 Hz from this process."""
    observer = Observer(ros_graph, interfaces.ACTUATOR_COMMANDS, 20.0, [STANDING])
    try:
        with boards_and_driver(request.node.name, command_timeout_s=1.0, board_silence_timeout_s=0.5) as run:
            assert call_set_bool(ros_graph, "/driver/enable", True)[0]
            yield run, observer
    finally:
        observer.close()
    assert all(p.process.returncode == 0 for p in run.processes)


def test_command_timeout_set_at_run_time_changes_when_the_boards_hold(
    ros_graph: Any, driver_and_boards: tuple[SuiteRun, Observer]
) -> None:
    """Commands every 50 ms: with a 1 s timeout no cycle holds for staleness; set to 10 ms, most cycles hold;
    back to 1 s, none again."""
    _, observer = driver_and_boards
    stale = ("rh5/driver", "count.stale_command_cycles")
    assert observer.growth(*stale) == 0
    assert _set(ros_graph, "driver", command_timeout_s=0.01) == [(True, "")]
    assert observer.growth(*stale) > 500  # ~80 % of 2200 cycles
    assert _set(ros_graph, "driver", command_timeout_s=1.0) == [(True, "")]
    assert observer.growth(*stale) == 0


def test_values_a_node_cannot_use_are_refused_with_the_reason(
    ros_graph: Any, driver_and_boards: tuple[SuiteRun, Observer]
) -> None:
    [(ok, reason)] = _set(ros_graph, "driver", router_port=7000)
    assert (ok, "read-only" in reason) == (False, True), reason
    [(ok, reason)] = _set(ros_graph, "sim_hardware", silent_boards=["LLKnee_Act9"])
    assert (ok, "unknown actuators ['LLKnee_Act9']" in reason) == (False, True), reason
    [(ok, reason)] = _set(ros_graph, "driver", command_timeout_s=-1.0)
    assert (ok, "out of range" in reason) == (False, True), reason


def test_forward_kinematics_settings_act_on_the_next_sample(
    ros_graph: Any, ros_test_environment: dict[str, str], log_dir: Path
) -> None:
    """The mapper's Newton cap set to 1 iteration: actuator readings that need more (an ankle pose alternating
    with the standing one, so the warm start is always off) are refused; set back to 20, they map again.
    (A refusal drops the warm start, and the standing pose is exact from the cold start: about every second
    sample is refused.)"""
    pitch = np.zeros(NUM_JOINTS)
    pitch[[JOINT_INDEX["LLAnklePitch"], JOINT_INDEX["LRAnklePitch"]]] = 0.3
    poses = [STANDING, robot_mapper().to_actuators(pitch).position]
    spec = NodeSpec("mapper", "rh5_hyrodyn_mapper", "mapper_node", {"publish_robot_description": False})
    observer = Observer(ros_graph, interfaces.ACTUATOR_STATES, 50.0, poses)
    try:
        with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"mapper"}) == set()
            rejected = ("rh5/mapper", "rejected.actuator_states")
            assert observer.growth(*rejected) == 0
            assert _set(ros_graph, "mapper", fk_max_iterations=1) == [(True, "")]
            assert observer.growth(*rejected) > 30  # of ~110 samples
            assert _set(ros_graph, "mapper", fk_max_iterations=20) == [(True, "")]
            assert observer.growth(*rejected) == 0
    finally:
        observer.close()
    assert run.processes[0].process.returncode == 0
