"""The mapper node: joint commands to actuator setpoints, actuator readings back to joint states.

It also publishes the generated URDF once on the latched ``robot_description`` topic.
Until the loop-closure kinematics of the parallel submechanisms exist, it maps only the
rotary joints that pass through unchanged (rad, Nm); parallel joints are not forwarded.
"""

from __future__ import annotations

from typing import Any

from std_msgs.msg import String

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_from_msg, joint_state_to_msg
from rh5_msgs_py.names import SUBMECHANISMS
from rh5_msgs_py.node_runtime import SuiteNode, run_node

PASS_THROUGH_JOINTS = tuple(j for s in SUBMECHANISMS if s.kind == "serial" for j in s.joints)


class MapperNode(SuiteNode):
    """Relays between joint space and actuator space."""

    def __init__(self) -> None:
        super().__init__(interfaces.MAPPER_NODE, "rh5_hyrodyn_mapper", "params/mapper.yaml")
        if self.params["publish_robot_description"]:
            from rh5_hyrodyn_mapper.model.urdf import generate_urdf  # noqa: PLC0415 (optional, costs ~0.1 s)

            self.advertise(interfaces.ROBOT_DESCRIPTION)(String(data=generate_urdf()))
        self._publish_actuator_commands = self.advertise(interfaces.ACTUATOR_COMMANDS)
        self._publish_joint_states = self.advertise(interfaces.JOINT_STATES)
        self.subscribe(interfaces.JOINT_COMMANDS, self._on_joint_commands)
        self.subscribe(interfaces.ACTUATOR_STATES, self._on_actuator_states)

    def _relay(self, msg: Any, publish: Any) -> None:
        names = [n for n in PASS_THROUGH_JOINTS if n in msg.name]
        if not names:
            return
        position, velocity, effort = joint_state_from_msg(msg, names)
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        publish(joint_state_to_msg(names, position, velocity, effort, stamp_ns=stamp_ns))

    def _on_joint_commands(self, msg: Any) -> None:
        self._relay(msg, self._publish_actuator_commands)

    def _on_actuator_states(self, msg: Any) -> None:
        self._relay(msg, self._publish_joint_states)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_hyrodyn_mapper mapper_node``."""
    run_node(MapperNode, args)
