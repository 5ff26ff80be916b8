"""Simulated RH5 hardware: models of what the boards and the robot do, free of ROS, and the node that serves them.

Layer: imports ``hardware`` (codec, transports, board map), the mapper and PyBullet; nothing above it.
Names resolve lazily: importing one model does not import the others (physics pulls in PyBullet).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .actuator_model import NOMINAL_DT, SUBSTEPS, ActuatorParams, ActuatorState, default_params
    from .actuators import ActuatorBank, ActuatorFlags, ActuatorMeasurement

_EXPORTS = {
    **dict.fromkeys(("NOMINAL_DT", "SUBSTEPS", "ActuatorParams", "ActuatorState", "default_params"), "actuator_model"),
    **dict.fromkeys(("ActuatorBank", "ActuatorFlags", "ActuatorMeasurement"), "actuators"),
}
__all__ = [
    "NOMINAL_DT",
    "SUBSTEPS",
    "ActuatorBank",
    "ActuatorFlags",
    "ActuatorMeasurement",
    "ActuatorParams",
    "ActuatorState",
    "default_params",
]
__getattr__ = lazy_exports(__name__, _EXPORTS)
