"""The planner node as a real process: ~/plan solves and publishes, ~/load republishes, refusals with reasons,
and the node's services keep answering while a solve runs."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_trajectory_from_msg, status_from_msg, wrench_from_msg
from rh5_msgs_py.names import JOINT_NAMES
from rh5_planner.cost_config import load_cost_config

STAGES = len(load_cost_config()["continuation"]) + 1
"""Box-FDDP solves per plan: the continuation stages of costs.yaml, then the problem as configured."""

pytestmark = pytest.mark.ros

MOTION = "squat_with_5kg_weights"  # converges in ~14 iterations, ~0.4 s
SLOW_MOTION = "fast_squats"  # ~1.3 s of solving: long enough to call other services meanwhile
PLAN_TIMEOUT_S = 120.0  # a solve takes ~3 s alone; next to two CPU burners, before the OpenMP default, over 30 s


class Observer:
    """The test's side: everything the planner publishes, and calls to its services."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticStatus
        from geometry_msgs.msg import WrenchStamped
        from trajectory_msgs.msg import JointTrajectory, MultiDOFJointTrajectory

        self.node = node
        self.trajectories: list[Any] = []
        self.base_trajectories: list[Any] = []
        self.wrenches: dict[str, list[Any]] = {"left": [], "right": []}
        self.progress: list[Any] = []
        topics = (
            (JointTrajectory, interfaces.PLANNED_TRAJECTORY, self.trajectories.append),
            (MultiDOFJointTrajectory, interfaces.PLANNED_BASE_TRAJECTORY, self.base_trajectories.append),
            (WrenchStamped, interfaces.PLANNED_WRENCH_LEFT, self.wrenches["left"].append),
            (WrenchStamped, interfaces.PLANNED_WRENCH_RIGHT, self.wrenches["right"].append),
            (DiagnosticStatus, interfaces.PLANNER_PROGRESS, lambda m: self.progress.append(status_from_msg(m))),
        )
        self.subscriptions = [node.create_subscription(t, topic.name, cb, topic.qos) for t, topic, cb in topics]
        self.clients: dict[str, Any] = {}

    def reset(self) -> None:
        self.trajectories.clear()
        self.base_trajectories.clear()
        for received in self.wrenches.values():
            received.clear()
        self.progress.clear()

    def spin_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        import rclpy

        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if done():
                return True
            rclpy.spin_once(self.node, timeout_sec=0.02)
        return done()

    def call_async(self, kind: Any, service: str, request: Any) -> Any:
        client = self.clients.get(service)
        if client is None:
            client = self.clients[service] = self.node.create_client(kind, service)
        assert client.wait_for_service(timeout_sec=10.0), f"{service} never appeared"
        return client.call_async(request)

    def call(self, kind: Any, service: str, request: Any, timeout_s: float = 10.0) -> Any:
        future = self.call_async(kind, service, request)
        assert self.spin_until(future.done, timeout_s), f"{service} did not answer within {timeout_s} s"
        return future.result()

    def trigger(self, service: str, timeout_s: float = 10.0) -> tuple[bool, str]:
        from std_srvs.srv import Trigger

        result = self.call(Trigger, service, Trigger.Request(), timeout_s)
        return result.success, result.message

    def set_string(self, name: str, value: str) -> None:
        from rcl_interfaces.msg import ParameterType, ParameterValue

        self._set(name, ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value))

    def set_int(self, name: str, value: int) -> None:
        from rcl_interfaces.msg import ParameterType, ParameterValue

        self._set(name, ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value))

    def _set(self, name: str, value: Any) -> None:
        from rcl_interfaces.msg import Parameter
        from rcl_interfaces.srv import SetParameters

        parameter = Parameter(name=name, value=value)
        result = self.call(SetParameters, "/planner/set_parameters", SetParameters.Request(parameters=[parameter]))
        assert result.results[0].successful, result.results[0].reason

    def close(self) -> None:
        for subscription in self.subscriptions:
            self.node.destroy_subscription(subscription)
        for client in self.clients.values():
            self.node.destroy_client(client)


@pytest.fixture(scope="module")
def planner(ros_graph: Any, ros_test_environment: dict[str, str]) -> Iterator[Observer]:
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "planner_node"
    parameters = {"motion": MOTION, "output_dir": str(log_dir / "plans")}
    bringup = Bringup("", (NodeSpec("planner", "rh5_planner", "planner_node", parameters),))
    observer = Observer(ros_graph)
    try:
        with SuiteRun(bringup, log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"planner"}) == set()
            observer.run = run  # type: ignore[attr-defined]
            yield observer
    finally:
        observer.close()
    assert run.processes[0].process.returncode == 0, run.processes[0].stderr_path.read_text()


def _longest(observer: Observer) -> Any:
    return max(observer.trajectories, key=lambda m: len(m.points), default=None)


def test_standing_hold_is_published_at_start(planner: Observer) -> None:
    """A late joiner still gets the start-up hold (reliable + transient local): the bent-knee standing pose."""
    assert planner.spin_until(lambda: bool(planner.trajectories) and bool(planner.base_trajectories), 10.0)
    hold = joint_trajectory_from_msg(planner.trajectories[0], JOINT_NAMES)
    assert len(hold.times) == 2
    assert hold.positions[0, JOINT_NAMES.index("LLKnee")] == pytest.approx(0.5, abs=0.01)  # the motion's knee bend
    assert hold.velocities is not None
    assert not hold.velocities.any()


def test_plan_solves_saves_and_publishes(planner: Observer) -> None:
    planner.reset()
    ok, message = planner.trigger("/planner/plan", PLAN_TIMEOUT_S)
    assert ok, message
    summary = json.loads(message)
    assert summary["motion"] == MOTION
    assert summary["verified"] is True
    assert summary["converged"] is True
    assert 1 <= summary["iterations"] <= 200
    assert summary["stop"] < 1e-7
    for key in ("cost", "solve_time_s", "knots", "file", "samples", "duration_s"):
        assert key in summary, key
    file = Path(summary["file"])
    assert file.is_file()
    assert file.name.startswith(f"{MOTION}_")
    assert file.suffix == ".rh5traj"

    # ~1000 samples per second of motion, every field, reliable + transient local
    assert planner.spin_until(lambda: any(len(m.points) > 100 for m in planner.trajectories), 10.0)
    trajectory = joint_trajectory_from_msg(_longest(planner), JOINT_NAMES)
    duration = trajectory.times[-1]
    assert duration == pytest.approx(summary["duration_s"], abs=1e-6)
    assert len(trajectory.times) == pytest.approx(1000.0 * duration + 1, abs=2)
    assert summary["samples"] == len(trajectory.times)
    for field in (trajectory.positions, trajectory.velocities, trajectory.accelerations, trajectory.efforts):
        assert field is not None
        assert field.shape == (len(trajectory.times), len(JOINT_NAMES))
    assert planner.spin_until(lambda: any(len(m.points) > 100 for m in planner.base_trajectories), 5.0)
    assert max(len(m.points) for m in planner.base_trajectories) == len(trajectory.times)

    # planned foot wrenches of the first sample: both feet carry the robot (~75 kg with the two 5 kg bars)
    assert planner.spin_until(lambda: all(planner.wrenches.values()), 5.0)
    fz = sum(wrench_from_msg(planner.wrenches[side][-1])[2] for side in ("left", "right"))
    assert 600.0 < fz < 900.0

    # progress: one status per Box-FDDP iteration, with the stop criterion
    iterations = [s for s in planner.progress if "cost" in s.values and "stop" in s.values]
    assert len(iterations) >= summary["iterations"] // 2
    assert all(s.values["motion"] == MOTION for s in iterations)

    # ~/load of the saved file publishes the same trajectory again
    planner.set_string("trajectory_file", str(file))
    planner.reset()
    ok, message = planner.trigger("/planner/load")
    assert ok, message
    assert planner.spin_until(lambda: any(len(m.points) > 100 for m in planner.trajectories), 10.0)
    assert len(_longest(planner).points) == len(trajectory.times)


@pytest.mark.parametrize(
    ("overrides", "reason"),
    [
        ("{not json", "not valid JSON"),
        ("[0.1]", "must be a JSON object"),
        ('{"no_such_parameter": 1}', "no_such_parameter"),
        ('{"total_time_s": "long"}', "total_time_s"),
    ],
)
def test_bad_motion_overrides_are_refused_with_the_reason(planner: Observer, overrides: str, reason: str) -> None:
    planner.set_string("motion_overrides", overrides)
    try:
        ok, message = planner.trigger("/planner/plan")
    finally:
        planner.set_string("motion_overrides", "{}")
    assert not ok
    assert message.startswith("bad parameters: motion_overrides: "), message
    assert reason in message


def test_unconverged_plan_is_saved_but_not_published(planner: Observer) -> None:
    """One iteration of the 10 cm jump (not verified): refused as not converged, file kept, nothing published."""
    planner.set_string("motion", "vertical_jump_10cm")
    planner.set_int("max_iterations", 1)
    planner.reset()
    try:
        ok, message = planner.trigger("/planner/plan", PLAN_TIMEOUT_S)
    finally:
        planner.set_int("max_iterations", 200)
        planner.set_string("motion", MOTION)
    assert not ok
    assert message.startswith("not converged: "), message
    summary = json.loads(message.removeprefix("not converged: "))
    assert summary["motion"] == "vertical_jump_10cm"
    assert summary["verified"] is False
    assert summary["converged"] is False
    assert 1 <= summary["iterations"] <= STAGES  # the cap holds per continuation stage of the wrench cone
    assert Path(summary["file"]).is_file()
    planner.spin_until(lambda: False, 0.3)
    assert not any(len(m.points) > 2 for m in planner.trajectories)


def test_services_answer_while_a_solve_runs(planner: Observer) -> None:
    from rcl_interfaces.srv import ListParameters
    from std_srvs.srv import Trigger

    planner.set_string("motion", SLOW_MOTION)
    planner.reset()
    try:
        plan = planner.call_async(Trigger, "/planner/plan", Trigger.Request())
        # wait until the solver iterates, then the parameter service and ~/plan must answer at once
        assert planner.spin_until(lambda: any("cost" in s.values for s in planner.progress), 15.0)
        assert not plan.done()
        started = time.monotonic()
        listed = planner.call(ListParameters, "/planner/list_parameters", ListParameters.Request(), timeout_s=2.0)
        latency = time.monotonic() - started
        assert "max_iterations" in listed.result.names
        assert not plan.done(), "the solve ended before the parameter service was asked: nothing was shown"
        busy, message = planner.trigger("/planner/plan", timeout_s=2.0)
        assert not busy
        assert message == f"busy: planning {SLOW_MOTION}"
        assert latency < 0.5
        assert planner.spin_until(plan.done, PLAN_TIMEOUT_S)
    finally:
        planner.set_string("motion", MOTION)
    result = plan.result()
    assert result.success, result.message
    summary = json.loads(result.message)
    assert summary["motion"] == SLOW_MOTION
    assert summary["converged"] is True


def _children(pid: int) -> list[int]:
    """Live processes whose parent is ``pid``."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.append(int(entry.name))
    return out


def test_sigint_during_a_solve_stops_the_solver_and_exits_cleanly(
    ros_graph: Any, ros_test_environment: dict[str, str]
) -> None:
    from std_srvs.srv import Trigger

    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "planner_sigint"
    parameters = {"motion": SLOW_MOTION, "output_dir": str(log_dir / "plans")}
    # its own namespace: the module's planner is still running
    bringup = Bringup("sigint", (NodeSpec("planner", "rh5_planner", "planner_node", parameters),))
    observer = Observer(ros_graph)
    try:
        with SuiteRun(bringup, log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"planner"}, namespace="/sigint") == set()
            node_pid = run.processes[0].process.pid
            observer.call_async(Trigger, "/sigint/planner/plan", Trigger.Request())
            assert observer.spin_until(lambda: bool(_children(node_pid)), 10.0), "no solver process started"
            solver_pids = _children(node_pid)
    finally:
        observer.close()
    assert run.processes[0].process.returncode == 0, run.processes[0].stderr_path.read_text()
    assert run.processes[0].summary() is not None
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and any(Path(f"/proc/{pid}").exists() for pid in solver_pids):
        time.sleep(0.05)
    assert not any(Path(f"/proc/{pid}").exists() for pid in solver_pids), "the solver outlived the node"
