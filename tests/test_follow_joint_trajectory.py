"""The stabilizer's ~/follow_joint_trajectory against a real rclpy ActionClient, the stabilizer a real process.

The test side stands in for the robot: it echoes every joint_commands position back as joint_states at 1 kHz
(a robot that tracks perfectly), so tolerances, feedback and results are those of real playback.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_to_msg, to_duration_msg
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop, LatestValue

pytestmark = pytest.mark.ros

ACTION = "/stabilizer_fjt/follow_joint_trajectory"


class EchoRobot:
    """Joint states = the last commanded positions (zero velocity while nothing moves), at 1 kHz."""

    def __init__(self, node: Any) -> None:
        from sensor_msgs.msg import JointState

        self.node = node
        self.pose: LatestValue[np.ndarray] = LatestValue()
        self.pose.set(np.zeros(NUM_JOINTS), 0)
        self._states = node.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
        node.create_subscription(JointState, interfaces.JOINT_COMMANDS.name, self._on_command, interfaces.STREAM_QOS)
        self.loop = DeadlineLoop(1000.0, self._publish, name="test-echo-robot")

    def _on_command(self, msg: Any) -> None:
        self.pose.set(np.array(msg.position), 0)

    def _publish(self, _now: int, _period: int) -> None:
        pose, _, _ = self.pose.try_get()
        self._states.publish(joint_state_to_msg(JOINT_NAMES, pose, np.zeros(NUM_JOINTS)))

    def spin_until(self, future: Any, timeout_s: float) -> Any:
        import rclpy

        end = time.monotonic() + timeout_s
        while not future.done() and time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)
        assert future.done(), f"no answer within {timeout_s} s"
        return future.result()


@pytest.fixture(scope="module")
def robot(ros_graph: Any, ros_test_environment: dict[str, str]) -> Iterator[tuple[EchoRobot, Any]]:
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient

    # state_timeout_s 0.5, as test_stabilizer_node's: the echo robot is a Python loop in this busy test process, and
    # next to two CPU burners it stalled past 0.1 s, so the stabilizer rightly held before a test preempted the goal
    # (the stale-state rule has its own tests, in rh5_joint_stabilizer/test/test_controller.py).
    spec = NodeSpec(
        "stabilizer_fjt",
        "rh5_joint_stabilizer",
        "stabilizer_node",
        {"state_timeout_s": 0.5, "goal_tolerance_rad": 0.01, "goal_time_tolerance_s": 1.0},
    )
    echo = EchoRobot(ros_graph)
    echo.loop.start()
    client = ActionClient(ros_graph, FollowJointTrajectory, ACTION)
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "stabilizer_fjt"
    try:
        with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"stabilizer_fjt"}) == set()
            assert client.wait_for_server(timeout_sec=10.0)
            yield echo, client
    finally:
        client.destroy()
        echo.loop.stop()
    assert run.processes[0].process.returncode == 0
    assert "Traceback" not in run.processes[0].stderr_path.read_text()


def _goal(names: list[str], seconds: float, amplitude: float = 0.05, end_at_zero: bool = True) -> Any:
    """A smooth bump of every joint: up and (if ``end_at_zero``) back within ``seconds``."""
    from control_msgs.action import FollowJointTrajectory
    from trajectory_msgs.msg import JointTrajectoryPoint

    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = names
    for t in np.linspace(0.0, seconds, 21):
        s = np.sin(np.pi * t / seconds) if end_at_zero else np.sin(0.5 * np.pi * t / seconds)
        point = JointTrajectoryPoint()
        point.positions = [float(amplitude * s)] * len(names)
        point.time_from_start = to_duration_msg(float(t))
        goal.trajectory.points.append(point)
    return goal


def _send(robot: EchoRobot, client: Any, goal: Any, feedback: list[Any] | None = None) -> Any:
    return robot.spin_until(
        client.send_goal_async(goal, feedback_callback=None if feedback is None else feedback.append), 5.0
    )


def test_goal_runs_with_feedback_and_succeeds(robot: tuple[EchoRobot, Any]) -> None:
    echo, client = robot
    feedback: list[Any] = []
    handle = _send(echo, client, _goal(list(JOINT_NAMES), 1.0), feedback)
    assert handle.accepted
    answer = echo.spin_until(handle.get_result_async(), 20.0)
    from action_msgs.msg import GoalStatus

    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result.error_string
    assert answer.result.error_code == 0
    assert len(feedback) >= 10
    last = feedback[-1].feedback
    assert list(last.joint_names) == list(JOINT_NAMES)
    assert len(last.desired.positions) == len(last.actual.positions) == len(last.error.positions) == NUM_JOINTS
    peak = max(max(f.feedback.desired.positions) for f in feedback)
    assert 0.03 < peak <= 0.0501  # the bump was played, not only the ramp to its start


def test_invalid_goal_is_rejected(robot: tuple[EchoRobot, Any]) -> None:
    echo, client = robot
    names = list(JOINT_NAMES)
    names[3] = "LLTail"
    handle = _send(echo, client, _goal(names, 1.0))
    assert not handle.accepted
    handle = _send(echo, client, _goal(list(JOINT_NAMES)[:10], 1.0))  # a partial goal
    assert not handle.accepted


def test_path_tolerance_violation_aborts_with_its_code(robot: tuple[EchoRobot, Any]) -> None:
    from action_msgs.msg import GoalStatus
    from control_msgs.action import FollowJointTrajectory
    from control_msgs.msg import JointTolerance

    echo, client = robot
    echo.pose.set(np.zeros(NUM_JOINTS), 0)
    goal = _goal(list(JOINT_NAMES), 1.0, amplitude=0.3)
    # The echo lags the reference by its loop and DDS: a 1e-5 rad path tolerance cannot hold while moving.
    goal.path_tolerance = [JointTolerance(name=n, position=1e-5) for n in JOINT_NAMES]
    handle = _send(echo, client, goal)
    assert handle.accepted
    answer = echo.spin_until(handle.get_result_async(), 20.0)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_code == FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
    assert "path tolerance violated" in answer.result.error_string


def test_new_goal_preempts_and_cancel_holds(robot: tuple[EchoRobot, Any]) -> None:
    from action_msgs.msg import GoalStatus

    echo, client = robot
    first = _send(echo, client, _goal(list(JOINT_NAMES), 4.0))
    assert first.accepted
    echo.spin_until(_sleep_future(echo.node, 1.0), 3.0)
    second = _send(echo, client, _goal(list(JOINT_NAMES), 4.0, amplitude=0.02))
    assert second.accepted
    answer = echo.spin_until(first.get_result_async(), 5.0)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert "preempted" in answer.result.error_string
    echo.spin_until(_sleep_future(echo.node, 0.5), 3.0)
    cancel = echo.spin_until(second.cancel_goal_async(), 5.0)
    assert len(cancel.goals_canceling) == 1
    answer = echo.spin_until(second.get_result_async(), 5.0)
    assert answer.status == GoalStatus.STATUS_CANCELED
    assert "holding" in answer.result.error_string


def _sleep_future(node: Any, seconds: float) -> Any:
    """A future that completes after ``seconds`` (spun like the others)."""
    from rclpy.task import Future

    future = Future()
    timer = None

    def fire() -> None:
        future.set_result(True)
        timer.cancel()

    timer = node.create_timer(seconds, fire)
    return future


def test_a_stop_during_a_goal_ends_the_node_cleanly(ros_graph: Any, ros_test_environment: dict[str, str]) -> None:
    """An operator's Ctrl-C while a goal plays: the node aborts the goal and exits 0, without a traceback (rcl
    refused the abort's status once SIGINT had shut the context down, and the node exited 1)."""
    from control_msgs.action import FollowJointTrajectory
    from rclpy.action import ActionClient

    spec = NodeSpec("stabilizer_stop", "rh5_joint_stabilizer", "stabilizer_node", {"state_timeout_s": 0.5})
    echo = EchoRobot(ros_graph)
    echo.loop.start()
    client = ActionClient(ros_graph, FollowJointTrajectory, "/stabilizer_stop/follow_joint_trajectory")
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "stabilizer_stop"
    try:
        with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"stabilizer_stop"}) == set()
            assert client.wait_for_server(timeout_sec=10.0)
            handle = _send(echo, client, _goal(list(JOINT_NAMES), 30.0))
            assert handle.accepted
            echo.spin_until(_sleep_future(echo.node, 0.5), 3.0)
    finally:
        client.destroy()
        echo.loop.stop()
    node = run.processes[0]
    assert node.process.returncode == 0
    log = node.stderr_path.read_text()
    assert "Traceback" not in log
    assert "goal aborted (code -1): the stabilizer is shutting down" in log
