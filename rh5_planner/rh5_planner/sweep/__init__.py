"""Capability maps: the paper's design analysis as parameter sweeps (``rh5-plan --sweep``), run on Ray.

* :mod:`.grid`: axes (motion parameters and design-limit factors), points, warm-start sources;
* :mod:`.point`: one point as plain data, solved in a worker; its result row;
* :mod:`.checkpoint`: results on disk as they arrive, for resuming;
* :mod:`.engine`: the scheduling loop and the in-process executor; :mod:`.ray_executor`: Ray tasks;
* :mod:`.progress`, :mod:`.table`, :mod:`.figures`: what the user sees; :mod:`.cli`: the command line.

Importing the package imports Crocoddyl first: the sweep's modules reach the RH5 model, which loads pinocchio, and
Crocoddyl must be loaded before it (design/crocoddyl_wheels.md), also in a Ray worker that unpickles a task.
"""

import crocoddyl  # noqa: F401  (before pinocchio)

from rh5_planner.sweep.engine import SerialExecutor, run_sweep
from rh5_planner.sweep.grid import Axis, Grid, GridError, SweepPoint, parse_axis
from rh5_planner.sweep.point import PointOutcome, PointTask, solve_point

__all__ = [
    "Axis",
    "Grid",
    "GridError",
    "PointOutcome",
    "PointTask",
    "SerialExecutor",
    "SweepPoint",
    "parse_axis",
    "run_sweep",
    "solve_point",
]
