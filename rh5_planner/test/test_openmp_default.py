"""The planner's processes run OpenMP with a one-thread default team (rh5_hyrodyn_mapper.openmp_default): libgomp's
per-core default made a Box-FDDP solve 40-80x slower next to other busy processes."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

OPENMP_THREADS = """
import ctypes
{imports}
path = next(line.split()[-1] for line in open("/proc/self/maps") if "libgomp" in line)
print(ctypes.CDLL(path).omp_get_max_threads())
"""


def _openmp_threads(imports: str, omp_num_threads: str | None = None) -> int:
    """libgomp's default team size in a fresh interpreter after ``imports`` (which must load libgomp)."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}
    if omp_num_threads is not None:
        env["OMP_NUM_THREADS"] = omp_num_threads
    code = OPENMP_THREADS.format(imports=imports)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120, check=True)
    return int(out.stdout.strip())


def test_the_planner_solves_with_a_one_thread_openmp_default() -> None:
    assert _openmp_threads("import rh5_planner.ocp") == 1


def test_the_mapper_sets_it_before_pinocchio_loads() -> None:
    assert _openmp_threads("import rh5_hyrodyn_mapper.model.robot\nimport pinocchio") == 1


def test_a_users_setting_stands() -> None:
    assert _openmp_threads("import rh5_planner.ocp", omp_num_threads="3") == 3


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="libgomp's own default is one thread on one core")
def test_without_the_suite_libgomp_would_take_every_core() -> None:
    """What the default changes: Pinocchio alone gives libgomp its per-core team."""
    assert _openmp_threads("import pinocchio") == len(os.sched_getaffinity(0))
