"""Orchestration: the bringup description, node processes, sessions with their service calls, experiments, the
``rh5`` command line and the generated launch and params files.

Layer: the top; it may import every other layer and package, and nothing imports it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .experiment import ExperimentError, ExperimentResult, ExperimentSettings, run_experiment
    from .launcher import Bringup, NodeSpec, SuiteRun, load_bringup
    from .session import SuiteSession

_EXPORTS = {
    **dict.fromkeys(("ExperimentError", "ExperimentResult", "ExperimentSettings", "run_experiment"), "experiment"),
    **dict.fromkeys(("Bringup", "NodeSpec", "SuiteRun", "load_bringup"), "launcher"),
    "SuiteSession": "session",
}
__all__ = [
    "Bringup",
    "ExperimentError",
    "ExperimentResult",
    "ExperimentSettings",
    "NodeSpec",
    "SuiteRun",
    "SuiteSession",
    "load_bringup",
    "run_experiment",
]
__getattr__ = lazy_exports(__name__, _EXPORTS)
