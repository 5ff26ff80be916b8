"""``rh5-plan --sweep MOTION key=start:stop:count ...``: the sweep's command line (called by rh5_planner.plan_cli).

Writes into ``--output-dir`` (default ``out/sweeps/MOTION``): the checkpoint (``sweep.json``, ``points.jsonl``,
``warm/``), ``status.json`` (counts and the points running now, with host and pid, rewritten as the sweep goes),
``sweep.csv`` and the figures. Running the same command again resumes: finished points are not solved again, and a
finished sweep only redraws its table and figures. Exit codes: 0 every point has a result, 1 some failed, 2 bad
input, 130 interrupted (resume with the same command).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, Final

from .checkpoint import Checkpoint, CheckpointMismatchError
from .engine import Executor, Running, SerialExecutor, SweepState, run_sweep
from .figures import actuator_base, minimal_specification, write_figures
from .grid import Grid, GridError, describe_axes, parse_axis
from .progress import SweepProgress, clock
from .table import summary, write_csv

__all__ = ["DEFAULT_SWEEP_DIR", "EXIT_INTERRUPTED", "run"]

DEFAULT_SWEEP_DIR: Final = Path("out/sweeps")
EXIT_INTERRUPTED: Final = 130


def _executor(args: argparse.Namespace) -> Executor:
    if args.engine == "serial":
        if args.address:
            msg = "--address needs --engine ray"
            raise GridError(msg)
        return SerialExecutor()
    from .ray_executor import RayExecutor  # noqa: PLC0415  (Ray only when it is used)

    return RayExecutor(address=args.address, workers=args.workers)


def _status_writer(folder: Path, progress: SweepProgress) -> Any:
    path = folder / "status.json"

    def on_progress(state: SweepState, running: Mapping[str, Running]) -> None:
        progress(state, running)
        status = {
            "total": state.total,
            "finished": state.finished,
            "failed": state.failed,
            "running": {
                p: {"host": r.host, "pid": r.pid, "started": r.started, "attempt": r.attempt}
                for p, r in running.items()
            },
            "updated": time.time(),
        }
        partial = path.with_suffix(".partial")
        partial.write_text(json.dumps(status, indent=1) + "\n", encoding="utf-8")
        os.replace(partial, path)

    return on_progress


def run(args: argparse.Namespace, base: Mapping[str, Any], out: IO[str], err: IO[str]) -> int:
    """Run the sweep of ``args.sweep`` = [MOTION, AXIS, ...] with the ``--set`` overrides ``base``."""
    motion, *axis_items = args.sweep
    if args.workers is not None and args.workers < 1:
        raise GridError(f"--workers must be >= 1, got {args.workers}")
    grid = Grid(
        motion,
        tuple(parse_axis(item) for item in axis_items),
        dict(base),
        chain=args.warm_chain,
        warm_start=not args.no_warm_start,
    )
    points = grid.points()  # validates every point's parameters before anything starts
    folder = Path(args.output_dir) if args.output_dir else DEFAULT_SWEEP_DIR / motion
    settings = {"max_iterations": args.max_iterations, "stop_threshold": args.stop_threshold}
    try:
        checkpoint = Checkpoint(folder, {"grid": grid.to_json(), "solver": settings}, restart=args.restart)
    except CheckpointMismatchError as error:
        raise GridError(str(error)) from None
    before = len(checkpoint.done())
    warm = sum(p.warm_from is not None for p in points)
    err.write(
        f"sweep {motion}: {describe_axes(grid.axes)} = {grid.size} points ({warm} warm-started along "
        f"{grid.axes[-1].key}), {before} done before; checkpoint {folder}\n"
    )
    progress = SweepProgress(err, label=f"sweep {motion}")
    start = time.time()
    if before < grid.size:
        # SIGINT interrupts (exit 130, resumable) also where it was inherited ignored, as by a background job;
        # the caller's handler is back once the sweep ends
        in_main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.default_int_handler) if in_main else None
        try:
            code, rows = _solve(args, grid, checkpoint, progress, err)
        finally:
            if previous is not None:
                signal.signal(signal.SIGINT, previous)
        if code:
            return code
        progress.finish(f"done in {clock(time.time() - start)}")
    else:
        rows = {p.id: checkpoint.rows[p.id] for p in points}
    ordered = [rows[p.id] for p in points if p.id in rows]
    files = [write_csv(ordered, grid.keys, folder / "sweep.csv")]
    if not args.no_figures:
        files += write_figures(grid, ordered, folder)
    out.write(summary(ordered) + "\n")
    for axis in grid.axes:
        if axis.is_limit:
            out.write(_minimal_text(grid, ordered, axis.key))
    out.write("written:\n" + "".join(f"  {f}\n" for f in files))
    return 1 if any(r.get("status") == "failed" for r in ordered) else 0


def _solve(
    args: argparse.Namespace, grid: Grid, checkpoint: Checkpoint, progress: SweepProgress, err: IO[str]
) -> tuple[int, dict[str, dict[str, Any]]]:
    """Solve the points not in the checkpoint on the chosen engine: (0 or EXIT_INTERRUPTED, rows by point id)."""
    executor = _executor(args)
    engine = "serial (this process)" if args.engine == "serial" else f"Ray {getattr(executor, 'address', '')}"
    err.write(f"engine: {engine}, {executor.workers} worker(s)\n")
    try:
        rows = run_sweep(
            grid,
            checkpoint,
            executor,
            max_iterations=args.max_iterations,
            stop_threshold=args.stop_threshold,
            nthreads=args.threads or 1,
            on_progress=_status_writer(checkpoint.folder, progress),
        )
    except (KeyboardInterrupt, SystemExit):
        progress.finish("interrupted")
        err.write(
            f"interrupted: {len(checkpoint.done())} of {grid.size} points are in {checkpoint.folder}; "
            "run the same command to resume\n"
        )
        return EXIT_INTERRUPTED, {}
    finally:
        executor.close()
    return 0, rows


def _minimal_text(grid: Grid, rows: list[dict[str, Any]], key: str) -> str:
    base = actuator_base(key)
    lines = [f"minimal {base[0] if base else key} for a feasible plan:"]
    for fixed, minimum in minimal_specification(grid, rows, key):
        where = ", ".join(f"{k} = {v:g}" for k, v in fixed.items()) or "the point"
        if minimum is None:
            lines.append(
                f"  {where}: none of x{', x'.join(f'{v:g}' for v in next(a for a in grid.axes if a.key == key).values)}"
            )
        elif base:
            lines.append(f"  {where}: x{minimum:g} = {minimum * base[1]:.0f} {base[2]}")
        else:
            lines.append(f"  {where}: x{minimum:g}")
    return "\n".join(lines) + "\n"
