"""The planner node: solves the selected motion and publishes the optimised trajectory.

At this stage ``~/plan`` answers that the Box-FDDP planner is not built yet, ``~/load``
publishes a trajectory file, and on start the node publishes the nominal standing pose
as a two-sample hold trajectory so that the rest of the suite has a reference.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from std_srvs.srv import Trigger

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_trajectory_to_msg
from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.trajectory_file import TrajectoryFileError, load_trajectory

HOLD_DURATION_S = 1.0


class PlannerNode(SuiteNode):
    """Offers ~/plan and ~/load and publishes planned_trajectory."""

    def __init__(self) -> None:
        super().__init__(interfaces.PLANNER_NODE, "rh5_planner", "params/planner.yaml")
        self._publish_trajectory = self.advertise(interfaces.PLANNED_TRAJECTORY)
        self.create_service(Trigger, interfaces.PLAN_SERVICE, self._on_plan)
        self.create_service(Trigger, interfaces.LOAD_SERVICE, self._on_load)
        standing = np.zeros(len(JOINT_NAMES))
        self._publish(np.array([0.0, HOLD_DURATION_S]), np.vstack([standing, standing]))

    def _publish(self, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray | None = None) -> None:
        stamp_ns = self.get_clock().now().nanoseconds
        self._publish_trajectory(
            joint_trajectory_to_msg(JOINT_NAMES, times, positions, velocities=velocities, stamp_ns=stamp_ns)
        )

    def _on_plan(self, _request: Any, response: Any) -> Any:
        response.success = False
        response.message = f"cannot plan {self.params['motion']!r}: the Box-FDDP planner is not built yet"
        return response

    def _on_load(self, _request: Any, response: Any) -> Any:
        path = self.params["trajectory_file"]
        if not path:
            response.success, response.message = False, "parameter trajectory_file is empty"
            return response
        try:
            data = load_trajectory(path)
        except (OSError, TrajectoryFileError) as err:
            response.success, response.message = False, str(err)
            return response
        self._publish(data.times, data.joint_positions(), data.joint_velocities())
        response.success = True
        response.message = f"published {len(data.times)} samples from {path}"
        return response


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_planner planner_node``."""
    run_node(PlannerNode, args)
