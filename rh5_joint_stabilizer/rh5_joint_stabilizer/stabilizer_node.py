"""The stabilizer node: plays the planned trajectory and stabilises it in joint space.

At this stage it holds the first sample of the latest ``planned_trajectory`` and publishes
it on ``joint_commands`` from a 100 Hz timer; the dedicated 1 kHz loop with PD +
feed-forward, ramp-in and the safety rules replaces this with the stabilizer issue.
"""

from __future__ import annotations

from typing import Any

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_to_msg, joint_trajectory_from_msg
from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node

HOLD_PERIOD_S = 0.01


class StabilizerNode(SuiteNode):
    """Holds the planned start pose until playback exists."""

    def __init__(self) -> None:
        super().__init__(interfaces.STABILIZER_NODE, "rh5_joint_stabilizer", "params/stabilizer.yaml")
        self._hold: Any = None
        self._publish_commands = self.advertise(interfaces.JOINT_COMMANDS)
        self.subscribe(interfaces.PLANNED_TRAJECTORY, self._on_trajectory)
        self.subscribe(interfaces.JOINT_STATES)
        self.create_timer(HOLD_PERIOD_S, self._tick)

    def _on_trajectory(self, msg: Any) -> None:
        trajectory = joint_trajectory_from_msg(msg, JOINT_NAMES)
        if len(trajectory.times) == 0:
            self.get_logger().warning("ignoring an empty planned_trajectory")
            return
        self._hold = trajectory.positions[0].copy()

    def _tick(self) -> None:
        if self._hold is None:
            return
        now_ns = self.get_clock().now().nanoseconds
        self._publish_commands(joint_state_to_msg(JOINT_NAMES, self._hold, stamp_ns=now_ns))


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_joint_stabilizer stabilizer_node``."""
    run_node(StabilizerNode, args)
