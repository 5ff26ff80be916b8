"""The planner node's solver child: ``python -m rh5_planner.solve_worker JOB``, one solve in its own process.

JOB is a JSON object (motion, overrides, file, max_iterations, stop_threshold, nthreads). The child writes
``RH5_PLAN {json}`` lines on stdout: ``{"progress": [iteration, cost, stop]}`` after every iteration, then
``{"result": solver log}`` once the trajectory file is saved, or ``{"error": "Type: text"}`` (exit code 1). It
ignores SIGINT (the node stops it when it is destroyed) and exits with code 3 once its parent is gone. A process of
its own because Crocoddyl holds the GIL for a whole solve (see :mod:`rh5_planner.planner_node`).
"""

from __future__ import annotations

import json
import os
import signal
import sys
from typing import Any, Final

LINE_PREFIX: Final = "RH5_PLAN "
"""Marks the child's protocol lines on stdout (anything else there is ignored)."""
PARENT_GONE_EXIT: Final = 3


def emit(kind: str, value: Any) -> None:
    """Write one protocol line ``RH5_PLAN {kind: value}`` and flush it."""
    sys.stdout.write(LINE_PREFIX + json.dumps({kind: value}) + "\n")
    sys.stdout.flush()


def run(job: dict[str, Any]) -> int:
    """Solve ``job``, save its trajectory file and report; the process's exit code."""
    parent = os.getppid()
    try:
        import crocoddyl  # noqa: F401, PLC0415  (before pinocchio: ../shared/design/crocoddyl_wheels.md)

        from rh5_planner.motions import get_motion  # noqa: PLC0415
        from rh5_planner.ocp import SolverSettings, solve  # noqa: PLC0415

        def progress(iteration: int, cost: float, stop: float) -> None:
            if os.getppid() != parent:
                os._exit(PARENT_GONE_EXIT)
            emit("progress", [iteration, cost, stop])

        settings = SolverSettings(
            max_iterations=job["max_iterations"],
            stop_threshold=job["stop_threshold"],
            nthreads=job["nthreads"],
            callback=progress,
        )
        result = solve(get_motion(job["motion"], job["overrides"]), settings)
        result.save(job["file"])
        emit("result", result.solver_log.to_dict())
    except Exception as err:  # reported to the node, which answers ~/plan with it
        emit("error", f"{type(err).__name__}: {err}")
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point: the JSON job is the only argument."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    args = sys.argv[1:] if argv is None else argv
    return run(json.loads(args[0]))


if __name__ == "__main__":
    sys.exit(main())
