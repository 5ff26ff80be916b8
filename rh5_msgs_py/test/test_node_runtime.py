"""run_node's life cycle, and the executor of a process with a real-time loop: every callback waits for the loop's
slack first."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from typing import Any

import pytest

from rh5_msgs_py.node_runtime import GatedExecutor, parse_summaries

pytestmark = pytest.mark.ros


def test_the_gated_executor_runs_each_callback_only_after_its_gate(ros_graph: Any) -> None:
    import rclpy

    node = rclpy.create_node("gated_executor_test", context=ros_graph.context)
    events: list[str] = []
    closed_until = time.monotonic() + 0.2

    def gate() -> None:
        """Stands for the loop's wait_for_slack: closed for the first 0.2 s."""
        events.append("gate")
        while time.monotonic() < closed_until:
            time.sleep(0.005)

    fired: list[float] = []
    node.create_timer(0.01, lambda: (events.append("callback"), fired.append(time.monotonic())))
    executor = GatedExecutor(gate)
    executor.add_node(node)
    try:
        while len(fired) < 3:
            executor.spin_once(timeout_sec=1.0)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert events[:6] == ["gate", "callback"] * 3  # each callback behind its own gate
    assert fired[0] >= closed_until  # the first waited for the gate to open


def test_the_gated_executor_completes_a_future_through_its_gate(ros_graph: Any) -> None:
    """rclpy.spin_until_future_complete goes through spin_once_until_future_complete: gated there too."""
    import rclpy
    from rclpy.task import Future

    node = rclpy.create_node("gated_future_test", context=ros_graph.context)
    gates: list[float] = []
    future = Future()
    node.create_timer(0.01, lambda: future.done() or future.set_result(len(gates)))
    executor = GatedExecutor(lambda: gates.append(time.monotonic()))
    executor.add_node(node)
    try:
        rclpy.spin_until_future_complete(node, future, executor=executor, timeout_sec=2.0)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert future.done()
    assert future.result() == 1  # the timer's callback ran behind one gate


STOPPED_WHILE_BUILDING = """
import os, signal
from rh5_joint_stabilizer.stabilizer_node import StabilizerNode
from rh5_msgs_py.node_runtime import run_node

def build():
    os.kill(os.getpid(), signal.SIG{name})  # the launcher saw the process and stops it: the node is not built yet
    return StabilizerNode()

run_node(build, ["stabilizer"])
"""


@pytest.mark.parametrize("name", ["INT", "TERM"])
def test_a_stop_while_the_node_is_built_ends_it_cleanly_once_built(
    ros_test_environment: dict[str, str], name: str
) -> None:
    """The stop waits for the node to exist, then ends it at once: exit 0 with the node's own summary (a stop
    under rclpy's handlers shut the context down under the half-built node, which then aborted now and then)."""
    child = subprocess.run(
        [sys.executable, "-c", STOPPED_WHILE_BUILDING.format(name=name)],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
        env=dict(os.environ),
    )
    assert child.returncode == 0, child.stderr[-2000:]
    assert [s["node"] for s in parse_summaries(child.stdout)] == ["stabilizer"], child.stdout[-2000:]


STACKS_THEN_STOP = """
import os, signal
from rh5_joint_stabilizer.stabilizer_node import StabilizerNode
from rh5_msgs_py.node_runtime import STACKS_SIGNAL, run_node

def build():
    node = StabilizerNode()
    os.kill(os.getpid(), STACKS_SIGNAL)  # an operator asks where the node is
    os.kill(os.getpid(), signal.SIGINT)
    return node

run_node(build, ["stabilizer"])
"""


def test_sigusr1_prints_every_threads_stack_and_the_node_goes_on(ros_test_environment: dict[str, str]) -> None:
    """``kill -USR1`` on a node prints where each of its threads is (faulthandler) and does not stop it: the
    node still ends cleanly on the SIGINT that follows, with its summary."""
    child = subprocess.run(
        [sys.executable, "-c", STACKS_THEN_STOP],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
        env=dict(os.environ),
    )
    assert child.returncode == 0, child.stderr[-2000:]
    assert "most recent call first" in child.stderr, child.stderr[-2000:]
    assert "in build" in child.stderr  # the main thread's stack, at the call that sent the signal
    assert [s["node"] for s in parse_summaries(child.stdout)] == ["stabilizer"], child.stdout[-2000:]
