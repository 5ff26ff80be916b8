"""Running a sweep: hand each point to an executor once its warm-start source is solved, checkpoint every result.

:func:`run_sweep` is the same for every executor. A point is submitted when the point that warm-starts it (the
grid's choice, :class:`rh5_planner.sweep.grid.Grid`) has a result; it then starts from that point's stored solution,
or cold if that one did not converge. Points already in the checkpoint are not solved again. Executors:

* :class:`SerialExecutor`: one point after the other in this process (no Ray; the baseline of ``bench/sweep.py``);
* :class:`rh5_planner.sweep.ray_executor.RayExecutor`: Ray tasks on a local instance or an existing cluster.
"""

from __future__ import annotations

import collections
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from ..motions import get_motion
from .checkpoint import Checkpoint
from .grid import Grid, SweepPoint
from .point import PointOutcome, PointTask, WarmStart, solve_point

__all__ = ["Executor", "Running", "SerialExecutor", "SweepState", "run_sweep", "task_of"]


@dataclass(frozen=True)
class Running:
    """A point a worker is solving."""

    point: str
    host: str
    pid: int
    started: float
    """time.time() at the start of its current attempt."""
    attempt: int


class Executor(Protocol):
    """Where points are solved."""

    workers: int
    """Points solved at the same time (for the ETA)."""

    def submit(self, task: PointTask, warm: WarmStart | None) -> None:
        """Queue ``task`` (starting from ``warm`` when given)."""
        ...

    def poll(self, timeout_s: float) -> list[PointOutcome]:
        """Results that arrived within ``timeout_s`` (possibly none)."""
        ...

    def running(self) -> dict[str, Running]:
        """The points being solved now, by point id."""
        ...

    def close(self) -> None:
        """Release the workers."""
        ...


class SerialExecutor:
    """Solves the queued points one by one in this process, when polled."""

    workers = 1

    def __init__(self) -> None:
        self._queue: collections.deque[tuple[PointTask, WarmStart | None]] = collections.deque()

    def submit(self, task: PointTask, warm: WarmStart | None) -> None:
        """Queue ``task``."""
        self._queue.append((task, warm))

    def poll(self, timeout_s: float) -> list[PointOutcome]:
        """Solve the next queued point (``timeout_s`` is not used: a solve takes what it takes)."""
        del timeout_s
        if not self._queue:
            return []
        task, warm = self._queue.popleft()
        outcome = solve_point(task, warm)
        outcome.row.setdefault("attempt", 1)
        return [outcome]

    def running(self) -> dict[str, Running]:
        """Nothing runs between polls."""
        return {}

    def close(self) -> None:
        """Nothing to release."""


@dataclass
class SweepState:
    """Counts for the progress display."""

    total: int
    done_before: int
    done: int = 0
    failed: int = 0
    running: int = 0
    started: float = 0.0

    @property
    def finished(self) -> int:
        """Points with a result, from before and from this run."""
        return self.done_before + self.done

    def eta_s(self, now: float) -> float | None:
        """Seconds left at the rate of this run (None until a point finished)."""
        if self.done == 0:
            return None
        rate = self.done / max(1e-9, now - self.started)
        return (self.total - self.finished) / rate


def task_of(
    grid: Grid, point: SweepPoint, *, max_iterations: int, stop_threshold: float, nthreads: int, warm_from: str
) -> PointTask:
    """The plain-data task of ``point``."""
    return PointTask(
        point=point.id,
        motion=grid.motion,
        values=dict(point.values),
        overrides=point.overrides(grid.base, get_motion(grid.motion)),
        scale=point.limit_scale().entries,
        max_iterations=max_iterations,
        stop_threshold=stop_threshold,
        nthreads=nthreads,
        warm_from=warm_from,
    )


def run_sweep(
    grid: Grid,
    checkpoint: Checkpoint,
    executor: Executor,
    *,
    max_iterations: int = 200,
    stop_threshold: float = 1e-7,
    nthreads: int = 1,
    on_progress: Callable[[SweepState, dict[str, Running]], None] | None = None,
    poll_s: float = 0.5,
) -> dict[str, dict[str, Any]]:
    """Solve every point of ``grid`` that ``checkpoint`` does not hold yet; returns every row by point id.

    Each result is checkpointed as it arrives, so an interrupted sweep (KeyboardInterrupt, SystemExit) loses only
    the points being solved. ``on_progress`` is called after every poll."""
    points: Sequence[SweepPoint] = grid.points()
    done = checkpoint.done()
    waiting = {p.id: p for p in points if p.id not in done}
    state = SweepState(len(points), len(points) - len(waiting), started=time.time())
    in_flight: set[str] = set()

    def submit_ready() -> None:
        for point_id, point in list(waiting.items()):
            source = points[point.warm_from] if point.warm_from is not None else None
            if source is not None and (source.id in waiting or source.id in in_flight):
                continue
            warm = checkpoint.warm_start(source.id) if source is not None else None
            task = task_of(
                grid,
                point,
                max_iterations=max_iterations,
                stop_threshold=stop_threshold,
                nthreads=nthreads,
                warm_from=source.id if warm is not None and source is not None else "",
            )
            executor.submit(task, warm)
            del waiting[point_id]
            in_flight.add(point_id)

    submit_ready()
    while in_flight:
        for outcome in executor.poll(poll_s):
            point_id = str(outcome.row["point"])
            if point_id not in in_flight:
                continue  # a duplicate (a retried task whose first attempt also reported)
            checkpoint.record(outcome)
            in_flight.discard(point_id)
            state.done += 1
            state.failed += outcome.row.get("status") == "failed"
        submit_ready()
        running = {k: v for k, v in executor.running().items() if k in in_flight}
        state.running = len(running)
        if on_progress is not None:
            on_progress(state, running)
    return {p.id: checkpoint.rows[p.id] for p in points if p.id in checkpoint.rows}
