"""Simulated RH5 hardware: models of what the boards and the robot do, free of ROS.

Names resolve lazily (PEP 562): importing one model does not import the others (physics pulls in PyBullet).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first use."""
    if name not in _EXPORTS:
        msg = f"module {__name__!r} has no attribute {name!r}"
        raise AttributeError(msg)
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value
