"""`rh5 up` and `rh5 experiment` respect the user's ROS environment: ROS_DOMAIN_ID and ROS_LOG_DIR when set,
`--domain-id` above both, a leased free domain only when nothing was chosen, a clear refusal of a bad id."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from rh5_bringup.orchestration.launcher import wait_for_nodes
from rh5_msgs_py.ros_env import chosen_domain_id

pytestmark = [pytest.mark.ros]

RH5 = str(Path(sys.prefix) / "bin" / "rh5")


def test_flag_beats_environment_beats_lease() -> None:
    assert chosen_domain_id(7, {"ROS_DOMAIN_ID": "173"}) == (7, "--domain-id")
    assert chosen_domain_id(None, {"ROS_DOMAIN_ID": " 173 "}) == (173, "ROS_DOMAIN_ID of the environment")
    assert chosen_domain_id(None, {"ROS_DOMAIN_ID": ""})[0] is None
    assert chosen_domain_id(None, {})[0] is None
    with pytest.raises(ValueError, match="'robot1' is not an integer"):
        chosen_domain_id(None, {"ROS_DOMAIN_ID": "robot1"})
    with pytest.raises(ValueError, match="--domain-id: 233 is outside"):
        chosen_domain_id(233, {})


@pytest.mark.parametrize("command", ["up", "experiment"])
def test_a_bad_domain_id_is_refused_with_the_reason(command: str, tmp_path: Path) -> None:
    args = [RH5, command, *(["fast_squats", "--out", str(tmp_path)] if command == "experiment" else [])]
    env = {**os.environ, "ROS_DOMAIN_ID": "lab-robot"}
    result = subprocess.run(args, capture_output=True, text=True, timeout=60, check=False, env=env)
    assert result.returncode == 2, result.stderr
    assert "ROS_DOMAIN_ID of the environment: 'lab-robot' is not an integer domain id" in result.stderr
    result = subprocess.run([*args, "--domain-id", "-1"], capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 2, result.stderr
    assert "--domain-id: -1 is outside the ROS domain ids 0..232" in result.stderr


def test_up_runs_in_the_users_domain_and_logs_where_the_user_said(
    ros_graph: Any, ros_test_environment: dict[str, str], tmp_path: Path
) -> None:
    """The suite comes up in ROS_DOMAIN_ID of the environment (where this test's observer sees its nodes), and
    rcl's log files go to the user's ROS_LOG_DIR, not into the run's folder."""
    domain = ros_test_environment["ROS_DOMAIN_ID"]
    ros_logs = tmp_path / "my_ros_logs"
    env = {**os.environ, "ROS_DOMAIN_ID": domain, "ROS_LOG_DIR": str(ros_logs), "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [RH5, "up", "--log-dir", str(tmp_path / "runs")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        missing = wait_for_nodes(ros_graph, {"control", "sim_hardware"}, timeout_s=60.0)
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    assert missing == set(), out[-2000:] + err[-2000:]
    assert f"ROS_DOMAIN_ID={domain} (ROS_DOMAIN_ID of the environment)" in out
    assert process.returncode == 0, out[-2000:] + err[-2000:]
    assert list(ros_logs.glob("*.log")), "no rcl log files in the user's ROS_LOG_DIR"
    assert not list((tmp_path / "runs").rglob("python_*.log")), "rcl logs went into the run folder"
