"""The simulated-hardware node: every actuator board of RH5, emulated at the protocol level.

It listens where the central router would (UDP, or CAN through python-can), decodes the
driver's NDLCom commands, runs the motor, transmission and cascaded-loop model of every
actuator in a dedicated thread, and answers every command burst at once with telemetry
(ticking every 1 ms on its own when no command comes).
Kinematic mode: the actuators move free of whole-body physics, starting in the nominal
standing pose. Faults are injected through parameters (see params/sim_hardware.yaml).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rh5_bringup.ndlcom.board_map import load_board_map
from rh5_bringup.sim.actuators import ActuatorBank
from rh5_bringup.sim.boards import BoardEmulator, BoardsServer, Faults
from rh5_bringup.transports import open_transport
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.names import ACTUATOR_NAMES, NUM_JOINTS
from rh5_msgs_py.node_runtime import SuiteNode, run_node


class SimHardwareNode(SuiteNode):
    """Stand-in for the FPGA boards and the robot."""

    def __init__(self) -> None:
        super().__init__(interfaces.SIM_HARDWARE_NODE, "rh5_bringup", "params/sim_hardware.yaml")
        params = self.params
        if params["mode"] != "kinematic":
            msg = "mode 'physics' (PyBullet) is not available yet: use mode:=kinematic"
            raise ValueError(msg)
        unknown = set(params["silent_boards"]) - set(ACTUATOR_NAMES)
        if unknown:
            msg = f"parameter silent_boards: unknown actuators {sorted(unknown)}"
            raise ValueError(msg)
        board_map = load_board_map()
        if params["transport"] == "udp":
            transport = open_transport(
                "udp", local=(params["listen_host"], params["listen_port"]), receivers=board_map.addresses()
            )
        else:
            transport = open_transport("can", interface="virtual", channel="rh5", receivers=board_map.addresses())
        self.transport = transport
        bank = ActuatorBank()
        bank.reset(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position)
        faults = Faults(
            drop_rate=params["drop_rate"],
            delay_s=params["delay_s"],
            corrupt_crc_rate=params["corrupt_crc_rate"],
            silent_boards=frozenset(params["silent_boards"]),
            sensor_noise_std=params["sensor_noise_std"],
        )
        self.emulator = BoardEmulator(board_map, transport, bank, faults)
        self.add_post_set_parameters_callback(self._update_faults)
        self.server = BoardsServer(self.emulator)
        self.context.on_shutdown(self.server.stop)
        self.server.start()

    def _update_faults(self, _changed: list[Any]) -> None:
        """Fault-injection parameters act at once (the spec callback has already validated them)."""
        params = self.params
        unknown = set(params["silent_boards"]) - set(ACTUATOR_NAMES)
        if unknown:
            self.get_logger().error(f"silent_boards: unknown actuators {sorted(unknown)} ignored")
        self.emulator.set_faults(
            Faults(
                drop_rate=params["drop_rate"],
                delay_s=params["delay_s"],
                corrupt_crc_rate=params["corrupt_crc_rate"],
                silent_boards=frozenset(params["silent_boards"]) & set(ACTUATOR_NAMES),
                sensor_noise_std=params["sensor_noise_std"],
            )
        )
        self.get_logger().info(f"faults now: {self.emulator.faults}")

    def summary(self) -> dict[str, Any]:
        """Adds the simulation mode, frame counts and loop timing to the base summary."""
        return {
            **super().summary(),
            "mode": self.params["mode"],
            "boards_emulated": len(self.emulator.board_map),
            "counts": dict(self.emulator.counts),
            "loop": self.server.stats().as_dict(),
        }

    def destroy_node(self) -> None:
        """Stop the loop, then close the link."""
        self.server.stop()
        self.transport.shutdown()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup sim_hardware_node``."""
    run_node(SimHardwareNode, args)
