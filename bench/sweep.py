"""Sweep bench: the local Ray default with 2 workers against one sequential process, and what warm starts save.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python bench/sweep.py [--motion squat_with_5kg_weights]
[--axis payload_kg_per_hand=0:10:6 --axis knee:velocity=1:2.5:8] [--set key=value ...] [--workers 2]
[--max-iterations 200]`` (48 points by default; ``OMP_NUM_THREADS=1`` gives the sequential process one thread, as Ray
gives each worker, so that it compares one core with two).

The same points are solved three times in one run, each into a fresh checkpoint: one after the other in this
process (the serial executor, one Crocoddyl thread per point, as in each Ray worker), on a local Ray instance with
``--workers`` workers (with warm starts, as the sequential run), and on Ray again with every point started cold.
First it measures the machine's own ceiling: how much faster ``--workers`` processes get through copies of a pure
CPU loop than one process (2.0 where each process has a core of its own). Prints the wall times and the speed-up of
Ray over the sequential process, with and without the instance's start-up, and the iterations the warm-started
points needed against the same points started cold, as ratios. The results of the sequential and the Ray run must
agree (same warm starts, so the same iterations per point).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)

from rh5_planner.plan_cli import parse_overrides
from rh5_planner.sweep.checkpoint import Checkpoint
from rh5_planner.sweep.engine import Executor, SerialExecutor, run_sweep
from rh5_planner.sweep.grid import Grid, parse_axis
from rh5_planner.sweep.ray_executor import RayExecutor


def _run(grid: Grid, executor_factory: Any, folder: Path, max_iterations: int) -> tuple[dict[str, Any], float, float]:
    """(rows, wall time with the executor's start-up, wall time of the sweep alone)."""
    checkpoint = Checkpoint(folder, {"grid": grid.to_json()})
    t0 = time.perf_counter()
    executor: Executor = executor_factory()
    t1 = time.perf_counter()
    try:
        rows = run_sweep(grid, checkpoint, executor, max_iterations=max_iterations, nthreads=1)
    finally:
        executor.close()
    t2 = time.perf_counter()
    return rows, t2 - t0, t2 - t1


def _spin(n: int) -> float:
    """A fixed amount of pure CPU work (no memory traffic); returns its wall time."""
    start = time.perf_counter()
    x = 0
    for i in range(n):
        x += i
    return time.perf_counter() - start


def machine_parallelism(workers: int, n: int = 15_000_000) -> float:
    """How much faster ``workers`` processes get through ``workers`` copies of the same loop than one process does
    one after the other (``workers`` on a machine that gives every process a core of its own)."""
    alone = _spin(n)
    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        pool.map(_spin, [1000] * workers)  # start the processes before timing
        start = time.perf_counter()
        pool.map(_spin, [n] * workers)
        together = time.perf_counter() - start
    return workers * alone / together


def main() -> None:
    """Solve the points three ways and print the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motion", default="squat_with_5kg_weights")
    parser.add_argument("--axis", action="append", default=[], help="key=start:stop:count (repeatable)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--max-iterations", type=int, default=200)
    args = parser.parse_args()
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    axes = tuple(parse_axis(a) for a in (args.axis or ["payload_kg_per_hand=0:10:6", "knee:velocity=1:2.5:8"]))
    base = parse_overrides(args.set)
    warm = Grid(args.motion, axes, base)
    cold = Grid(args.motion, axes, base, warm_start=False)
    with tempfile.TemporaryDirectory(prefix="rh5_sweep_bench_") as scratch:
        root = Path(scratch)
        ceiling = machine_parallelism(args.workers)
        print(f"this machine: {args.workers} processes run a pure CPU loop {ceiling:.2f}x as fast as one", flush=True)
        print(f"{args.motion}: {warm.size} points over {', '.join(a.key for a in axes)}", flush=True)
        serial, serial_wall, _ = _run(warm, SerialExecutor, root / "serial", args.max_iterations)
        print(f"sequential (this process): {serial_wall:.1f} s", flush=True)
        ray_rows, ray_wall, ray_sweep = _run(
            warm, lambda: RayExecutor(workers=args.workers), root / "ray", args.max_iterations
        )
        print(
            f"Ray, {args.workers} workers: {ray_wall:.1f} s ({ray_sweep:.1f} s after the instance started)", flush=True
        )
        cold_rows, cold_wall, _ = _run(
            cold, lambda: RayExecutor(workers=args.workers), root / "cold", args.max_iterations
        )
        print(f"Ray, {args.workers} workers, every point cold: {cold_wall:.1f} s", flush=True)

    same = all(
        serial[p]["status"] == ray_rows[p]["status"] and serial[p]["iterations"] == ray_rows[p]["iterations"]
        for p in serial
    )
    warmed = [p for p, row in serial.items() if row.get("warm_from")]
    it_warm = sum(int(serial[p]["iterations"]) for p in warmed)
    it_cold = sum(int(cold_rows[p]["iterations"]) for p in warmed)
    all_warm = sum(int(r["iterations"]) for r in serial.values())
    all_cold = sum(int(r["iterations"]) for r in cold_rows.values())
    s_warm = sum(float(ray_rows[p]["solve_s"]) for p in warmed)
    s_cold = sum(float(cold_rows[p]["solve_s"]) for p in warmed)
    status_changed = [p for p in warmed if serial[p]["status"] != cold_rows[p]["status"]]
    print()
    for label, rows in (("sequential", serial), ("Ray", ray_rows), ("Ray, cold", cold_rows)):
        solve = sum(float(r["solve_s"]) for r in rows.values()) / len(rows)
        cpu = sum(float(r["cpu_s"]) for r in rows.values()) / len(rows)
        print(f"{label}: per point {solve:.2f} s wall, {cpu:.2f} s CPU of its process")
    print(
        f"speed-up, Ray {args.workers} workers over one sequential process: {serial_wall / ray_wall:.2f}x "
        f"({serial_wall / ray_sweep:.2f}x without the instance's start-up); results identical: {same}"
    )
    print(
        f"warm starts: {len(warmed)} of {len(serial)} points warm-started; their iterations warm/cold "
        f"{it_warm}/{it_cold} = {it_warm / max(1, it_cold):.2f} (solve time on Ray {s_warm:.1f}/{s_cold:.1f} s = "
        f"{s_warm / max(1e-9, s_cold):.2f}); whole sweep {all_warm}/{all_cold} = {all_warm / max(1, all_cold):.2f}"
    )
    print(f"verdicts that differ between warm and cold starts: {status_changed or 'none'}")


if __name__ == "__main__":
    main()
