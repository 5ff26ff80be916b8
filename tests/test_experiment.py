"""The product's main job, shortened for CI: `rh5 experiment` plans a one-squat fast_squats, plays it on the
PyBullet robot through the whole suite, records a bag and writes the report; `rh5 report` rewrites it."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rh5_bringup.experiment import SIM_STALL_S, _Monitor

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RH5 = str(Path(sys.prefix) / "bin" / "rh5")
SHORT_SQUAT = ["--set", "n_squats=1", "--set", "total_time_s=2.3", "--hold", "0.5"]


@pytest.fixture(scope="module")
def experiment(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    out = tmp_path_factory.mktemp("experiment")
    result = subprocess.run(
        [RH5, "experiment", "fast_squats", *SHORT_SQUAT, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=420,
        check=False,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    return result, out


def _path_after(label: str, text: str) -> Path:
    match = re.search(rf"^rh5 experiment: {label} (\S+)$", text, re.MULTILINE)
    assert match, f"no '{label}' line in:\n{text}"
    return Path(match.group(1))


def test_experiment_runs_end_to_end_without_falling(experiment: tuple[subprocess.CompletedProcess[str], Path]) -> None:
    result, _ = experiment
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "fast_squats: completed" in result.stdout
    assert "planned now" in result.stdout
    assert f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} (chosen)" in result.stdout  # the user's, not a lease
    # Into a pipe (a log), progress is lines, not carriage returns: the planning bar ends with its verdict, and
    # the motion's status line appears once per state (and every few seconds), not once per 0.1 s.
    assert "\r" not in result.stderr
    assert re.search(r"^planning fast_squats \[#+\.*\] it \d+/\d+ .* converged$", result.stderr, re.MULTILINE)
    status_lines = [line for line in result.stderr.splitlines() if line.startswith("fast_squats: ")]
    assert 2 <= len(status_lines) < 40, status_lines


def test_bag_holds_the_suite_streams(experiment: tuple[subprocess.CompletedProcess[str], Path]) -> None:
    from rosbags.highlevel import AnyReader

    result, _ = experiment
    bag = _path_after("bag", result.stdout)
    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.duration > 2.3e9  # at least the motion itself
    seconds = 2.3
    for topic in ("/joint_states", "/joint_commands", "/actuator_states", "/actuator_commands"):
        assert counts.get(topic, 0) > 0.5 * 1000 * seconds, (topic, counts)
    assert counts.get("/sim/base_pose", 0) > 50 * seconds, counts
    assert counts.get("/clock", 0) > 50 * seconds, counts  # the simulation runs on its own, slower clock
    assert counts.get("/planned_trajectory", 0) >= 1, counts


def test_each_ground_truth_sample_is_recorded_once(experiment: tuple[subprocess.CompletedProcess[str], Path]) -> None:
    """/clock comes with each ground-truth sample, taken about every 4 ms of simulated time (ground_truth_rate_hz
    250; at the end of the board cycle that crossed each multiple, so not exactly 4 ms apart): never the same
    sample twice (here the simulation runs slower than the publishing timer's wall clock)."""
    import numpy as np
    from rosbags.highlevel import AnyReader

    result, _ = experiment
    with AnyReader([_path_after("bag", result.stdout)]) as reader:
        clock = [c for c in reader.connections if c.topic == "/clock"]
        stamps = [
            (msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)
            for msg in (reader.deserialize(raw, con.msgtype) for con, _, raw in reader.messages(connections=clock))
        ]
    steps = np.diff(stamps)
    assert len(stamps) > 500
    assert (steps > 0).all(), f"{np.count_nonzero(steps <= 0)} repeated /clock values"
    assert np.median(steps) >= 3_500_000


def test_report_is_written_and_rewritten(experiment: tuple[subprocess.CompletedProcess[str], Path]) -> None:
    result, out = experiment
    report = _path_after("report", result.stdout)
    pngs = sorted(p.name for p in report.glob("*.png"))
    markdown = list(report.glob("*.md"))
    assert pngs, f"no plots in {report}"
    assert markdown, f"no Markdown summary in {report}"
    text = markdown[0].read_text(encoding="utf-8")
    assert "LLAnkle" in text or "ankle" in text.lower()
    again = subprocess.run(
        [RH5, "report", str(_path_after("bag", result.stdout)), "--out", str(out / "again")],
        capture_output=True,
        text=True,
        timeout=180,
        check=False,
    )
    assert again.returncode == 0, again.stderr
    assert sorted(p.name for p in (out / "again").glob("*.png")) == pngs


def test_report_rejects_a_folder_that_is_not_a_bag(tmp_path: Path) -> None:
    result = subprocess.run([RH5, "report", str(tmp_path)], capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 2
    assert "report:" in result.stderr


def test_playback_times_out_on_simulated_time_or_a_stalled_simulation() -> None:
    """The simulation runs slower than real time: the play budget counts simulated seconds while /clock advances,
    and wall seconds without a simulation; a simulation that stopped publishing /clock times out too."""
    monitor = object.__new__(_Monitor)
    now = time.monotonic()
    monitor.sim_time_s, monitor.sim_time_arrived = 105.0, now  # 5 simulated s after a start at 100 s
    assert not monitor.timed_out(now - 60.0, 100.0, budget_s=10.0)  # a minute of wall time, 5 s simulated
    assert monitor.timed_out(now - 60.0, 94.0, budget_s=10.0)  # 11 s simulated
    monitor.sim_time_arrived = now - SIM_STALL_S - 1.0
    assert monitor.timed_out(now - 60.0, 100.0, budget_s=10.0)  # /clock stalled
    monitor.sim_time_s = None  # kinematic mode: wall time
    assert monitor.timed_out(now - 11.0, None, budget_s=10.0)
    assert not monitor.timed_out(now - 9.0, None, budget_s=10.0)
