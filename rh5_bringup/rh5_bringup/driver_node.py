"""The driver node: the 1 kHz link between actuator_commands/actuator_states and the boards.

At this stage no board transport exists: ``~/enable``, ``~/estop`` and ``~/reset_estop``
keep their latching semantics, and the node echoes the latest command as the
measured state (ideal hardware), 100 times a second. The NDLCom transports and the
dedicated 1 kHz loop replace the echo with the hardware-layer issue.
"""

from __future__ import annotations

from typing import Any

from std_srvs.srv import SetBool, Trigger

from rh5_msgs_py import interfaces
from rh5_msgs_py.node_runtime import SuiteNode, run_node

ECHO_PERIOD_S = 0.01


class DriverNode(SuiteNode):
    """Enable/estop state machine plus an ideal-hardware echo."""

    def __init__(self) -> None:
        super().__init__(interfaces.DRIVER_NODE, "rh5_bringup", "params/driver.yaml")
        self.enabled = False
        self.estopped = False
        self._latest: Any = None
        self._publish_states = self.advertise(interfaces.ACTUATOR_STATES)
        self.subscribe(interfaces.ACTUATOR_COMMANDS, self._on_command)
        self.create_service(SetBool, interfaces.ENABLE_SERVICE, self._on_enable)
        self.create_service(Trigger, interfaces.ESTOP_SERVICE, self._on_estop)
        self.create_service(Trigger, interfaces.RESET_ESTOP_SERVICE, self._on_reset_estop)
        self.create_timer(ECHO_PERIOD_S, self._tick)

    def _on_command(self, msg: Any) -> None:
        self._latest = msg

    def _tick(self) -> None:
        if self._latest is not None:
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
        response.success, response.message = True, "emergency stop latched; boards hold"
        return response

    def _on_reset_estop(self, _request: Any, response: Any) -> Any:
        self.estopped = False
        response.success, response.message = True, "emergency stop cleared; call ~/enable to drive again"
        return response

    def summary(self) -> dict[str, Any]:
        """Adds the enable/estop state to the base summary."""
        return {**super().summary(), "enabled": self.enabled, "estopped": self.estopped}


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup driver_node``."""
    run_node(DriverNode, args)
