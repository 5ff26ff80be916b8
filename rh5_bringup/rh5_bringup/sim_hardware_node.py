"""The simulated-hardware node: emulates the actuator boards (and later the robot's physics).

At this stage it declares its model and fault-injection parameters and idles; board
emulation over NDLCom comes with the hardware-layer issue, PyBullet physics with the
end-to-end experiment issue.
"""

from __future__ import annotations

from typing import Any

from rh5_msgs_py import interfaces
from rh5_msgs_py.node_runtime import SuiteNode, run_node


class SimHardwareNode(SuiteNode):
    """Stand-in for the FPGA boards and the robot."""

    def __init__(self) -> None:
        super().__init__(interfaces.SIM_HARDWARE_NODE, "rh5_bringup", "params/sim_hardware.yaml")

    def summary(self) -> dict[str, Any]:
        """Adds the simulation mode to the base summary."""
        return {**super().summary(), "mode": self.params["mode"], "boards_emulated": 0}


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup sim_hardware_node``."""
    run_node(SimHardwareNode, args)
