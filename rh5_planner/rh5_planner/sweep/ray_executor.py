"""Ray as the sweep's engine: one task per point, on a local Ray instance or an existing cluster.

Without an address, :class:`RayExecutor` starts a private local instance for the sweep (one worker per core by
default, ``workers``), on 127.0.0.1, without dashboard, with a small object store and its session files in a
short folder of its own under /tmp, and shuts it down at the end. With ``address`` (``--address``, e.g.
``127.0.0.1:6379`` or ``auto``) it connects to a running cluster and leaves it running; every node must have this
package installed (the same venv), since tasks import it to rebuild their problem.

Ray authenticates with a token (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH`` or ~/.ray/auth_token, which a local
instance creates); towards an existing cluster the token is sent whenever one is found, unless ``RAY_AUTH_MODE`` says
otherwise.

A task is :func:`rh5_planner.sweep.point.solve_point` on a :class:`~rh5_planner.sweep.point.PointTask` (plain data)
and returns the point's row and solution. Ray retries a task whose worker or node died (``max_retries``); the
row's ``attempt`` says which attempt delivered it (0: unknown, the monitor did not answer). Tasks report their start
(host, pid) to a small actor, which the progress display and ``status.json`` read for the points running now.
"""

from __future__ import annotations

import logging
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Final

import ray
import ray.exceptions

from .engine import Running
from .point import PointOutcome, PointTask, WarmStart, failed_outcome, solve_point

__all__ = ["DEFAULT_OBJECT_STORE_MB", "RayExecutor"]

DEFAULT_OBJECT_STORE_MB: Final = 256
"""Object store of the local instance: results are small (a solution is ~0.1 MB), Ray's default is 30 % of RAM."""
MAX_RETRIES: Final = 3


class _Monitor:
    """Start reports of the tasks (an actor): the points running now and how often each was started."""

    def __init__(self) -> None:
        self._starts: dict[str, list[tuple[str, int, float]]] = {}

    def started(self, point: str, host: str, pid: int) -> int:
        """Record a start of ``point``; returns its attempt number (1 for the first)."""
        self._starts.setdefault(point, []).append((host, pid, time.time()))
        return len(self._starts[point])

    def snapshot(self) -> dict[str, tuple[str, int, float, int]]:
        """The latest start of every point that was started: (host, pid, time, attempt)."""
        return {p: (*starts[-1], len(starts)) for p, starts in self._starts.items()}


def _solve(task: PointTask, warm: WarmStart | None, monitor: Any) -> PointOutcome:
    """The Ray task: report the start (without waiting: a task blocked in ray.get hands its CPU to another task, and
    two points would then share one core), then solve."""
    monitor.started.remote(task.point, platform.node(), os.getpid())
    return solve_point(task, warm)


def _use_token_if_available() -> None:
    """Authenticate to an existing cluster with the token ``ray start`` uses, as ``ray.init(address="auto")`` does:
    Ray sends it only in token mode, which an explicit address does not switch on by itself."""
    if "RAY_AUTH_MODE" in os.environ:
        return
    path = os.environ.get("RAY_AUTH_TOKEN_PATH") or str(Path.home() / ".ray" / "auth_token")
    if os.environ.get("RAY_AUTH_TOKEN") or Path(path).is_file():
        os.environ["RAY_AUTH_MODE"] = "token"


class RayExecutor:
    """Points as Ray tasks (see the module docstring)."""

    def __init__(
        self,
        *,
        address: str | None = None,
        workers: int | None = None,
        object_store_mb: int = DEFAULT_OBJECT_STORE_MB,
        max_retries: int = MAX_RETRIES,
    ) -> None:
        if ray.is_initialized():
            msg = "Ray is already initialised in this process"
            raise RuntimeError(msg)
        self._temp_dir: str | None = None
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no usage reports off the machine unless asked for
        if address:
            _use_token_if_available()
            loopback = address.rsplit(":", 1)[0] in ("127.0.0.1", "localhost")
            ray.init(
                address=address,
                log_to_driver=False,
                logging_level=logging.WARNING,
                # a cluster on loopback: this driver's node is the 127.0.0.1 one, not the machine's network address
                _node_ip_address="127.0.0.1" if loopback else None,
            )
        else:
            # unix socket paths live in the temp dir and must stay under 107 characters: keep it short
            self._temp_dir = tempfile.mkdtemp(prefix=f"rh5ray_{os.getpid()}_", dir="/tmp")
            ray.init(
                num_cpus=workers or os.cpu_count() or 1,
                include_dashboard=False,
                object_store_memory=object_store_mb * 2**20,
                log_to_driver=False,
                logging_level=logging.WARNING,
                _temp_dir=self._temp_dir,
                _node_ip_address="127.0.0.1",
            )
        self.address = address or "local"
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._monitor = ray.remote(num_cpus=0, max_restarts=-1)(_Monitor).remote()
        self._remote = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=False)(_solve)
        self._tasks: dict[Any, PointTask] = {}
        self._running: dict[str, Running] = {}

    def submit(self, task: PointTask, warm: WarmStart | None) -> None:
        """Start ``task`` as a Ray task (Ray queues it until a worker is free)."""
        ref = self._remote.options(name=f"rh5_sweep_{task.point}").remote(task, warm, self._monitor)
        self._tasks[ref] = task

    def poll(self, timeout_s: float) -> list[PointOutcome]:
        """Results that arrived within ``timeout_s``; a task that Ray gave up on becomes a ``failed`` row."""
        if not self._tasks:
            return []
        refs = list(self._tasks)
        ready, _ = ray.wait(refs, num_returns=1, timeout=timeout_s)
        if ready:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
        out = []
        for ref in ready:
            task = self._tasks.pop(ref)
            try:
                out.append(ray.get(ref))
            except ray.exceptions.RayError as err:
                out.append(failed_outcome(task, f"{type(err).__name__}: {err}"))
        starts = self._refresh_running()
        for outcome in out:  # the task reported its start seconds before it delivered: the count is complete
            outcome.row["attempt"] = starts.get(str(outcome.row["point"]), (0, 0, 0.0, 0))[3]
        return out

    def _refresh_running(self) -> dict[str, tuple[str, int, float, int]]:
        """Ask the monitor for the starts; returns its snapshot (empty if it did not answer)."""
        try:
            snapshot = ray.get(self._monitor.snapshot.remote(), timeout=10)
        except (ray.exceptions.RayError, TimeoutError):
            return {}  # keep the last known running set
        pending = {t.point for t in self._tasks.values()}
        self._running = {
            p: Running(p, host, pid, started, attempt)
            for p, (host, pid, started, attempt) in snapshot.items()
            if p in pending
        }
        return snapshot

    def running(self) -> dict[str, Running]:
        """The points whose latest attempt started and has not delivered yet."""
        return dict(self._running)

    def close(self) -> None:
        """Disconnect; a local instance is shut down and its session folder removed."""
        self._tasks.clear()
        if ray.is_initialized():
            ray.shutdown()
        if self._temp_dir is not None:
            shutil.rmtree(self._temp_dir, ignore_errors=True)
            self._temp_dir = None
