"""The hardware layer: NDLCom frames and payloads, transports to the boards, the 1 kHz driver core and node.

Layer: imports only ``rh5_msgs_py``, the mapper, python-can (for the CAN transport) and ROS 2 messages, so a robot
PC that runs only the driver needs neither PyBullet, matplotlib, Crocoddyl nor rosbags (tests/test_layers.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .driver import ActuatorCommand, ActuatorReadings, DriverCore
    from .ndlcom.board_map import BoardMap, load_board_map
    from .transports import Transport, open_transport

_EXPORTS = {
    **dict.fromkeys(("ActuatorCommand", "ActuatorReadings", "DriverCore"), "driver"),
    **dict.fromkeys(("BoardMap", "load_board_map"), "ndlcom.board_map"),
    **dict.fromkeys(("Transport", "open_transport"), "transports"),
}
__all__ = [
    "ActuatorCommand",
    "ActuatorReadings",
    "BoardMap",
    "DriverCore",
    "Transport",
    "load_board_map",
    "open_transport",
]
__getattr__ = lazy_exports(__name__, _EXPORTS)
