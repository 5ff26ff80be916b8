"""rh5_planner: whole-body motion planning for RH5 with contact-stability soft-constrained Box-FDDP (Crocoddyl).

* :mod:`.motions`: the motion library (parameters, contact sequences, the paper's named motions);
* :mod:`.ocp`: the optimal control problem: robot, costs, dynamics, warm start, :func:`solve`, :class:`PlanResult`;
* :mod:`.cost_config`, :mod:`.feet`: the cost weights (config/costs.yaml) and the sole's support rectangle;
* :mod:`.actuator_bounds`, :mod:`.actuator_constraints`: the linear actuators' limits inside the problem;
* :mod:`.limit_scale`, :mod:`.limit_analysis`, :mod:`.feasibility`, :mod:`.design`: scaled limits, the limit
  analysis of a plan, the paper's feasibility table and the design-improvement heuristic;
* :mod:`.interpolation`, :mod:`.publishing`, :mod:`.plots`: 1 kHz samples, messages and figures of a plan;
* :mod:`.planner_node`, :mod:`.plan_cli`, :mod:`.solve_worker`, :mod:`.sweep`: the node, ``rh5-plan`` and sweeps.

Names resolve lazily (PEP 562, :func:`rh5_msgs_py.lazy_exports.lazy_exports`): importing the package imports neither
Crocoddyl nor pinocchio, so the node and the command line start fast and load the planner only when they plan.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_hyrodyn_mapper.openmp_default import default_openmp_to_one_thread
from rh5_msgs_py.lazy_exports import lazy_exports

default_openmp_to_one_thread()  # before anything here imports Crocoddyl or Pinocchio

if TYPE_CHECKING:
    from .cost_config import load_cost_config
    from .design import improve_design
    from .feasibility import FeasibilityTable
    from .interpolation import interpolate
    from .limit_analysis import LimitAnalysis, analyse
    from .limit_scale import LimitScale
    from .motions import MOTIONS, VERIFIED_MOTIONS, MotionError, MotionSpec, get_motion
    from .ocp import PlanResult, SolverSettings, build_problem, build_robot, solve

_EXPORTS = {
    **dict.fromkeys(("MOTIONS", "VERIFIED_MOTIONS", "MotionError", "MotionSpec", "get_motion"), "motions"),
    **dict.fromkeys(("PlanResult", "SolverSettings", "build_problem", "build_robot", "solve"), "ocp"),
    "load_cost_config": "cost_config",
    "LimitScale": "limit_scale",
    **dict.fromkeys(("LimitAnalysis", "analyse"), "limit_analysis"),
    "FeasibilityTable": "feasibility",
    "improve_design": "design",
    "interpolate": "interpolation",
}
__all__ = [
    "MOTIONS",
    "VERIFIED_MOTIONS",
    "FeasibilityTable",
    "LimitAnalysis",
    "LimitScale",
    "MotionError",
    "MotionSpec",
    "PlanResult",
    "SolverSettings",
    "analyse",
    "build_problem",
    "build_robot",
    "get_motion",
    "improve_design",
    "interpolate",
    "load_cost_config",
    "solve",
]

__getattr__ = lazy_exports(__name__, _EXPORTS)
