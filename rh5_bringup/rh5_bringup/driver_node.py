"""The driver node: the 1 kHz link between actuator_commands/actuator_states and the boards.

At this stage no board transport exists: ``~/enable``, ``~/estop`` and ``~/reset_estop``
keep their latching semantics, and the node publishes the latest command as the
measured state (ideal hardware, standing in the nominal pose until the first command)
every millisecond. The NDLCom transports and the
dedicated 1 kHz loop replace the echo with the hardware-layer issue.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_to_msg
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import DeadlineLoop


class DriverNode(SuiteNode):
    """Enable/estop state machine plus an ideal-hardware echo."""

    def __init__(self) -> None:
        super().__init__(interfaces.DRIVER_NODE, "rh5_bringup", "params/driver.yaml")
        self.enabled = False
        self.estopped = False
        # Ideal hardware standing still in the nominal pose until the first command arrives.
        standing = robot_mapper().to_actuators(np.zeros(len(JOINT_NAMES))).position
        self._latest: Any = joint_state_to_msg(ACTUATOR_NAMES, standing, np.zeros(len(ACTUATOR_NAMES)))
        self._publish_states = self.advertise(interfaces.ACTUATOR_STATES)
        self._publish_estop = self.advertise(interfaces.DRIVER_ESTOP)
        self._publish_estop(Bool(data=False))
        self.subscribe(interfaces.ACTUATOR_COMMANDS, self._on_command)
        self.create_service(SetBool, interfaces.ENABLE_SERVICE, self._on_enable)
        self.create_service(Trigger, interfaces.ESTOP_SERVICE, self._on_estop)
        self.create_service(Trigger, interfaces.RESET_ESTOP_SERVICE, self._on_reset_estop)
        self.loop = DeadlineLoop(self.params["rate_hz"], self._tick, name="driver-echo")
        self.context.on_shutdown(self.loop.stop)
        self.loop.start()

    def _on_command(self, msg: Any) -> None:
        self._latest = msg

    def _tick(self, _now_ns: int, _period_ns: int) -> None:
        self._publish_states(self._latest)

    def _on_enable(self, request: Any, response: Any) -> Any:
        if request.data and self.estopped:
            response.success, response.message = False, "refused: emergency stop is latched (call ~/reset_estop)"
            return response
        self.enabled = bool(request.data)
        response.success, response.message = True, "enabled" if self.enabled else "disabled"
        return response

    def _on_estop(self, _request: Any, response: Any) -> Any:
        self.estopped, self.enabled = True, False
        self._publish_estop(Bool(data=True))
        response.success, response.message = True, "emergency stop latched; boards hold"
        return response

    def _on_reset_estop(self, _request: Any, response: Any) -> Any:
        self.estopped = False
        self._publish_estop(Bool(data=False))
        response.success, response.message = True, "emergency stop cleared; call ~/enable to drive again"
        return response

    def destroy_node(self) -> None:
        """Stop the loop thread before the node goes away."""
        self.loop.stop()
        super().destroy_node()

    def summary(self) -> dict[str, Any]:
        """Adds the enable/estop state to the base summary."""
        return {**super().summary(), "enabled": self.enabled, "estopped": self.estopped}


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup driver_node``."""
    run_node(DriverNode, args)
