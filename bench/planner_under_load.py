"""The planner next to busy processes: one Box-FDDP solve with the suite's one-thread OpenMP default team against
libgomp's per-core default, idle and next to CPU burners, each in a fresh process, alternating.

Run: ``.venv/bin/python bench/planner_under_load.py [--motion fast_squats] [--burners 2] [--rounds 1]``.
Prints the solve times and the ratio per-core / one-thread (above 1: the default helps).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys

from loop_floor import cpu_burners

SOLVE = """
import time
from rh5_planner.motions import get_motion
from rh5_planner.ocp import SolverSettings, solve
start = time.perf_counter()
result = solve(get_motion({motion!r}), SolverSettings())
print(time.perf_counter() - start, result.solver_log.iterations)
"""


def solve_seconds(motion: str, omp_num_threads: str | None) -> float:
    """One solve in a fresh interpreter: its wall time in ``solve()`` (s)."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_NUM_THREADS"}
    if omp_num_threads is not None:
        env["OMP_NUM_THREADS"] = omp_num_threads
    code = SOLVE.format(motion=motion)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.split()[0])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motion", default="fast_squats")
    parser.add_argument("--burners", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    cores = str(len(os.sched_getaffinity(0)))
    variants = {"suite default (1 thread)": None, f"libgomp default ({cores} threads)": cores}
    for label, load in (("idle", 0), (f"{args.burners} burners", args.burners)):
        times: dict[str, list[float]] = {name: [] for name in variants}
        with cpu_burners(load):
            for _ in range(args.rounds):
                for name, value in variants.items():
                    times[name].append(solve_seconds(args.motion, value))
                    print(f"  {label:>10}  {name:<28} {times[name][-1]:8.2f} s", flush=True)
        one, per_core = (statistics.median(t) for t in times.values())
        print(f"{args.motion} {label}: per-core / one-thread = {per_core / one:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
