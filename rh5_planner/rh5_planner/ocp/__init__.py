"""Contact-stability soft-constrained Box-FDDP on the full RH5 model (paper, "Analysis and control using DDP").

Our own builders on Crocoddyl's public API (crocoddyl.utils.biped is not API and is not used here), one module a job:

* :mod:`.settings`: :class:`SolverSettings` of a solve;
* :mod:`.robot`: RH5 with its payload, Crocoddyl state and actuation, nominal state, (scaled) planning limits;
* :mod:`.ik`: whole-body IK for the nominal pose and the warm start;
* :mod:`.costs`: the cost sum of every knot (config/costs.yaml) and the contact-stability regions;
* :mod:`.models`: the action model of every knot (contact dynamics, touch-down impulses, the torque box);
* :mod:`.warm_start`: the kinematic state guess;
* :mod:`.builder`: the shooting problem of a motion (:func:`build_problem`) with its actuator bounds;
* :mod:`.solver`: :func:`solve`, the continuation over the cost weights and the actuator-limit refinement;
* :mod:`.result`: :class:`PlanResult`, what a solve returns, and its trajectory file.

``solve(motion, settings)`` builds, solves and returns a :class:`PlanResult` with states, torques, contact
wrenches and CoPs per foot per knot, the contact phases and the solver log. Scaled limits (``limit_scale``) are
described in :mod:`rh5_planner.limit_scale`, the cost configuration in :mod:`rh5_planner.cost_config`.

Importing the package imports Crocoddyl first: its modules load pinocchio, and Crocoddyl must be loaded before it
(design/crocoddyl_wheels.md).
"""

import crocoddyl  # noqa: F401  (before pinocchio)

from .builder import BuiltProblem, build_problem
from .costs import CONTACT_STABILITY_FORMS, ContactCone, contact_cones
from .ik import nominal_configuration
from .result import PlanResult
from .robot import RobotSetup, build_robot
from .settings import ProgressCallback, SolverSettings
from .solver import solve

__all__ = [
    "CONTACT_STABILITY_FORMS",
    "BuiltProblem",
    "ContactCone",
    "PlanResult",
    "ProgressCallback",
    "RobotSetup",
    "SolverSettings",
    "build_problem",
    "build_robot",
    "contact_cones",
    "nominal_configuration",
    "solve",
]
