"""The planner node's solver child run as the node runs it: ``python -m rh5_planner.solve_worker JOB``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from rh5_msgs_py.trajectory_file import load_trajectory
from rh5_planner.solve_worker import LINE_PREFIX

MOTION = "squat_with_5kg_weights"  # converges in ~14 iterations, ~0.4 s


def run_worker(job: dict[str, Any]) -> tuple[int, list[dict[str, Any]]]:
    """Run the child on ``job``; its exit code and protocol lines."""
    argv = [sys.executable, "-m", "rh5_planner.solve_worker", json.dumps(job)]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    lines = [json.loads(line[len(LINE_PREFIX) :]) for line in done.stdout.splitlines() if line.startswith(LINE_PREFIX)]
    return done.returncode, lines


def test_solves_saves_and_reports(tmp_path: Path) -> None:
    file = tmp_path / "squat.rh5traj"
    job = {
        "motion": MOTION,
        "overrides": {},
        "file": str(file),
        "max_iterations": 100,
        "stop_threshold": 1e-7,
        "nthreads": 1,
    }
    code, lines = run_worker(job)
    assert code == 0, lines
    progress = [entry["progress"] for entry in lines if "progress" in entry]
    assert [p[0] for p in progress] == list(range(1, len(progress) + 1))
    assert "result" in lines[-1]
    log = lines[-1]["result"]
    assert log["converged"]
    assert log["iterations"] == len(progress)
    data = load_trajectory(file)
    assert data.motion["name"] == MOTION
    assert data.solver_log["iterations"] == log["iterations"]


def test_reports_an_error_and_exits_1(tmp_path: Path) -> None:
    job = {
        "motion": "no_such_motion",
        "overrides": {},
        "file": str(tmp_path / "x.rh5traj"),
        "max_iterations": 10,
        "stop_threshold": 1e-7,
        "nthreads": 1,
    }
    code, lines = run_worker(job)
    assert code == 1
    assert len(lines) == 1
    assert "no_such_motion" in lines[0]["error"]
