"""The executor of a process with a real-time loop: every callback waits for the loop's slack first."""

from __future__ import annotations

import time
from typing import Any

import pytest

from rh5_msgs_py.node_runtime import GatedExecutor

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
