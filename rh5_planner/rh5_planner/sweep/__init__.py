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
