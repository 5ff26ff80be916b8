"""OpenMP's default team in the suite's processes: one thread, unless the user set ``OMP_NUM_THREADS``.

Pinocchio loads libgomp, whose default team is one thread per core. A team whose other thread is descheduled makes
every parallel region wait: next to two CPU burners on this 2-core machine, a Box-FDDP solve of fast_squats took
7-148 s with it, and 4.1-4.8 s with a one-thread default, at a cost of ~6 % on an idle machine
(``bench/planner_under_load.py``; set ``OMP_NUM_THREADS`` to the core count on a machine that only plans).
Crocoddyl's own derivative-pass threads (``problem.nthreads``) are set per problem and still run. libgomp reads the
variable once, when it loads, so this runs when the mapper or the planner package is first imported, before either
imports Pinocchio or Crocoddyl.
"""

from __future__ import annotations

import os

__all__ = ["OPENMP_THREADS_VARIABLE", "default_openmp_to_one_thread"]

OPENMP_THREADS_VARIABLE = "OMP_NUM_THREADS"


def default_openmp_to_one_thread() -> None:
    """Set ``OMP_NUM_THREADS=1`` in this process's environment unless it is set already."""
    os.environ.setdefault(OPENMP_THREADS_VARIABLE, "1")
