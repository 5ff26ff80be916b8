"""Simulated RH5 hardware: models of what the boards and the robot do, free of ROS.

Names resolve lazily (PEP 562), so ``python -m rh5_bringup.sim.actuators`` runs the module only once.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .actuators import (
        NOMINAL_DT,
        SUBSTEPS,
        ActuatorBank,
        ActuatorMeasurement,
        ActuatorParams,
        ActuatorState,
        Mode,
        Status,
        StepCost,
        default_params,
        measure_step_cost,
    )

_EXPORTS = dict.fromkeys(
    (
        "NOMINAL_DT",
        "SUBSTEPS",
        "ActuatorBank",
        "ActuatorMeasurement",
        "ActuatorParams",
        "ActuatorState",
        "Mode",
        "Status",
        "StepCost",
        "default_params",
        "measure_step_cost",
    ),
    "actuators",
)
__all__ = [
    "NOMINAL_DT",
    "SUBSTEPS",
    "ActuatorBank",
    "ActuatorMeasurement",
    "ActuatorParams",
    "ActuatorState",
    "Mode",
    "Status",
    "StepCost",
    "default_params",
    "measure_step_cost",
]


def __getattr__(name: str) -> Any:
    """Import the submodule that defines ``name`` on first use."""
    if name not in _EXPORTS:
        msg = f"module {__name__!r} has no attribute {name!r}"
        raise AttributeError(msg)
    value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
    globals()[name] = value
    return value
