"""The mapper node: joint commands to actuator setpoints, actuator readings back to joint states.

It also publishes the generated URDF once on the latched ``robot_description`` topic.
Until the loop-closure kinematics of the parallel submechanisms exist, it maps only the
rotary joints that pass through unchanged (rad, Nm); parallel joints are not forwarded.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np
from std_msgs.msg import String

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_from_msg, joint_state_to_msg, time_to_ns
from rh5_msgs_py.names import JOINT_INDEX, JOINT_NAMES, SUBMECHANISMS
from rh5_msgs_py.node_runtime import SuiteNode, run_node

PASS_THROUGH_JOINTS = tuple(j for s in SUBMECHANISMS if s.kind == "serial" for j in s.joints)
PASS_THROUGH_INDEX = np.array([JOINT_INDEX[j] for j in PASS_THROUGH_JOINTS])


class MapperNode(SuiteNode):
    """Relays between joint space and actuator space."""

    def __init__(self) -> None:
        super().__init__(interfaces.MAPPER_NODE, "rh5_hyrodyn_mapper", "params/mapper.yaml")
        self.rejected: Counter[str] = Counter()
        if self.params["publish_robot_description"]:
            from rh5_hyrodyn_mapper.model.urdf import generate_urdf  # noqa: PLC0415 (optional, costs ~0.1 s)

            self.advertise(interfaces.ROBOT_DESCRIPTION)(String(data=generate_urdf()))
        self._publish_actuator_commands = self.advertise(interfaces.ACTUATOR_COMMANDS)
        self._publish_joint_states = self.advertise(interfaces.JOINT_STATES)
        self.subscribe(interfaces.JOINT_COMMANDS, self._on_joint_commands)
        self.subscribe(interfaces.ACTUATOR_STATES, self._on_actuator_states)

    def _on_joint_commands(self, msg: Any) -> None:
        try:
            position, velocity, effort = joint_state_from_msg(msg, JOINT_NAMES)
        except ValueError as err:
            self._reject("joint_commands", err)
            return
        self._publish_actuator_commands(
            joint_state_to_msg(
                PASS_THROUGH_JOINTS,
                position[PASS_THROUGH_INDEX],
                None if velocity is None else velocity[PASS_THROUGH_INDEX],
                None if effort is None else effort[PASS_THROUGH_INDEX],
                stamp_ns=time_to_ns(msg.header.stamp),
            )
        )

    def _on_actuator_states(self, msg: Any) -> None:
        try:
            position, velocity, effort = joint_state_from_msg(msg, PASS_THROUGH_JOINTS)
        except ValueError as err:
            self._reject("actuator_states", err)
            return
        stamp_ns = time_to_ns(msg.header.stamp)
        self._publish_joint_states(
            joint_state_to_msg(PASS_THROUGH_JOINTS, position, velocity, effort, stamp_ns=stamp_ns)
        )

    def _reject(self, topic: str, err: Exception) -> None:
        self.rejected[topic] += 1
        self.get_logger().warning(f"rejected a {topic} message: {err}", throttle_duration_sec=1.0)

    def summary(self) -> dict[str, Any]:
        """Adds the rejected message counts to the base summary."""
        return {**super().summary(), "rejected": dict(self.rejected)}


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_hyrodyn_mapper mapper_node``."""
    run_node(MapperNode, args)
