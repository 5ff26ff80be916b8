"""``rh5-plan --sweep`` on Ray: the same six cheap points (a 20-knot squat, payload x knee velocity factor) through the
installed command line, on the local default (a private Ray instance, one worker per core) and on a real two-node
Ray cluster that the test starts on 127.0.0.1 (a head node and a worker node, one CPU each, as separate
``ray start --block`` processes, stopped by SIGTERM at the end, which stops every process they started). The cluster
run is interrupted after its first result and resumed; during the resumed run the test kills (SIGKILL) the worker
process that solves a cold-started point. Both tables must agree, the resume must solve only the missing points,
and the killed worker's point must be delivered by Ray's retry. An integration test (here, not in the package's
tests, so that colcon test does not run it a second time).
"""

from __future__ import annotations

import contextlib
import csv
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

MOTION = "squat_with_5kg_weights"
CHEAP = ["--set", "total_time_s=0.6", "--set", "hold_s=0.1", "--set", "com_range_m=0.1", "--max-iterations", "40"]
AXES = ["payload_kg_per_hand=0:10:3", "knee:velocity=1,2"]
COLD = {"p0000", "p0002", "p0004"}
"""The points that no neighbour warm-starts (knee velocity factor 1): long enough to kill the worker solving one."""
COMPARED = ("status", "converged", "feasible", "limiting", "iterations", "warm_from", "limiting_use", "peak.velocity")


TOKEN = secrets.token_hex(32)


def _environment() -> dict[str, str]:
    """The tests' Ray processes: no usage reports off the machine, token authentication with a token of their own."""
    env = dict(os.environ)
    env.update(RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=TOKEN)
    return env


def _sweep(folder: Path, *extra: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "rh5_planner.plan_cli", "--sweep", MOTION, *AXES, *CHEAP]
    command += ["--output-dir", str(folder), "--no-figures", *extra]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_environment())


def _finish(process: subprocess.Popen[str], timeout: float = 120.0) -> tuple[int, str, str]:
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        pytest.fail(f"the sweep did not finish in {timeout} s:\n{err[-3000:]}")
    return process.returncode, out, err


def _table(folder: Path) -> dict[str, dict[str, str]]:
    with (folder / "sweep.csv").open(encoding="utf-8") as file:
        return {row["point"]: row for row in csv.DictReader(file)}


def _lines(folder: Path) -> list[dict[str, object]]:
    path = folder / "points.jsonl"
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.endswith("}")]


def _wait_for(predicate, timeout: float, what: str) -> object:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(f"timed out after {timeout} s waiting for {what}")
    return None


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _stop(process: subprocess.Popen[str]) -> None:
    """SIGTERM a ``ray start --block`` process (it stops every process it started), SIGKILL if it hangs."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=10)


@contextlib.contextmanager
def ray_cluster() -> Iterator[str]:
    """A head node and a worker node on 127.0.0.1, one CPU each; yields the head's address."""
    ray = str(Path(sys.executable).parent / "ray")
    temp_dir = f"/tmp/rh5ray_{os.getpid()}"  # unix socket paths below it must stay under 107 characters
    port = _free_port()
    common = ["--block", "--num-cpus=1", "--node-ip-address=127.0.0.1", "--object-store-memory=100000000"]
    head_command = [ray, "start", "--head", f"--port={port}", "--include-dashboard=false", f"--temp-dir={temp_dir}"]
    head_command += common
    processes: list[subprocess.Popen[str]] = []
    try:
        processes.append(
            subprocess.Popen(
                head_command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True, env=_environment()
            )
        )
        address = f"127.0.0.1:{port}"
        _wait_for(lambda: Path(temp_dir, "ray_current_cluster").exists() or processes[0].poll() is not None, 60, "head")
        assert processes[0].poll() is None, "the head node did not start"
        worker_command = [ray, "start", f"--address={address}", *common]
        processes.append(
            subprocess.Popen(
                worker_command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True, env=_environment()
            )
        )
        yield address
    finally:
        for process in reversed(processes):
            _stop(process)
        shutil.rmtree(temp_dir, ignore_errors=True)


@pytest.mark.slow
def test_sweep_on_local_ray_and_on_a_two_node_cluster_resumes_and_survives_a_killed_worker(tmp_path: Path) -> None:
    started = time.monotonic()
    # 1. the local default: a private Ray instance with one worker per core
    local = tmp_path / "local"
    code, out, err = _finish(_sweep(local))
    assert code == 0, err[-3000:]
    assert "engine: Ray local" in err
    assert "6 points" in out
    reference = _table(local)
    assert len(reference) == 6
    assert {row["status"] for row in reference.values()} <= {"feasible", "over_limits", "not_converged"}
    assert sum(row["warm_from"] != "" for row in reference.values()) >= 1  # warm starts took place
    progress = [line for line in err.splitlines() if line.startswith(f"sweep {MOTION} [")]
    assert progress
    assert all(part in progress[-1] for part in ("6/6 done, ", " running, ", " failed, ", " elapsed, ETA "))

    with ray_cluster() as address:
        # 2. interrupted after its first result ... (the six cheap points take about a second together: when the
        # cold-started points beat the signal, no point is left to kill a worker on; interrupt a fresh sweep again,
        # at most three times)
        for attempt in range(3):
            cluster = tmp_path / f"cluster{attempt}"
            first = _sweep(cluster, "--address", address)
            _wait_for(lambda: len(_lines(cluster)) >= 1 or first.poll() is not None, 90, "the first result")  # noqa: B023
            first.send_signal(signal.SIGINT)
            code, _, err = _finish(first)
            if code != 0 or COLD - {str(row["point"]) for row in _lines(cluster)}:
                break  # interrupted with a cold-started point left, for the resumed run's worker to die on
        assert code == 130, err[-3000:]
        assert "run the same command to resume" in err
        before = {str(row["point"]) for row in _lines(cluster)}
        assert 1 <= len(before) < 6

        # 3. ... resumed; a worker process dies while it solves a cold-started point
        (cluster / "status.json").unlink(missing_ok=True)
        resumed = time.time()
        second = _sweep(cluster, "--address", address)
        cold = COLD - before

        def running_cold() -> tuple[str, int] | None:
            try:
                status = json.loads((cluster / "status.json").read_text(encoding="utf-8"))
            except (OSError, ValueError):
                return None
            if status.get("updated", 0) < resumed:
                return None
            candidates = [(v["started"], p, v["pid"]) for p, v in status["running"].items() if p in cold]
            return max(candidates)[1:] if candidates else None

        victim, pid = _wait_for(running_cold, 90, "a running cold-started point")  # type: ignore[misc]
        os.kill(int(pid), signal.SIGKILL)
        code, out, err = _finish(second)
        assert code == 0, err[-3000:]
        assert f"{len(before)} done before" in err
        assert "engine: Ray " + address in err

    # every point solved exactly once over both runs: the resume solved nothing again
    points = [str(row["point"]) for row in _lines(cluster)]
    assert sorted(points) == sorted(reference)
    table = _table(cluster)
    # the killed worker's point was delivered by Ray's retry
    assert int(table[victim]["attempt"]) >= 2
    assert table[victim]["status"] != "failed"
    # the same results on both engines
    for point, row in reference.items():
        for column in COMPARED:
            expected, got = row[column], table[point][column]
            try:
                assert float(got) == pytest.approx(float(expected), rel=1e-9), (point, column)
            except ValueError:
                assert got == expected, (point, column)
    assert time.monotonic() - started < 150
