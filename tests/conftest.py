"""Fixtures shared by the integration tests (the session-wide rules are in the repository's conftest.py)."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest


def _write_joint_trajectory(path: Path, seconds: float, amplitude: float = 0.0) -> Path:
    """A trajectory file in which every joint follows ``amplitude * sin(pi t)`` for ``seconds`` (0: the zero pose
    held), the base standing still with both feet in contact; returns its path."""
    from rh5_hyrodyn_mapper.model import model_hash
    from rh5_msgs_py.names import NUM_JOINTS
    from rh5_msgs_py.trajectory_file import NQ, NV, TrajectoryData, save_trajectory

    t = np.arange(0.0, seconds, 0.03)
    states = np.zeros((len(t), NQ + NV))
    states[:, 6] = 1.0  # base quaternion (x, y, z, w) = identity
    states[:, 7 : 7 + NUM_JOINTS] = amplitude * np.sin(np.pi * t)[:, None]
    states[:, NQ + 6 :] = amplitude * np.pi * np.cos(np.pi * t)[:, None]
    data = TrajectoryData(
        times=t,
        states=states,
        controls=np.zeros((len(t) - 1, NUM_JOINTS)),
        contact_wrenches=np.zeros((len(t), 2, 6)),
        contact_phases=np.ones((len(t), 2), dtype=bool),
        cop=np.zeros((len(t), 2, 2)),
        motion={"name": path.stem},
        model_hash=model_hash(),
    )
    return save_trajectory(path, data)


@pytest.fixture(scope="session")
def write_joint_trajectory() -> Callable[..., Path]:
    """``write(path, seconds, amplitude=0.0)``: a joint-sine (or hold) trajectory file for the nodes that read one."""
    return _write_joint_trajectory


def _free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that nothing is bound to right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="session")
def free_udp_port() -> Callable[[], int]:
    """``free_udp_port()``: a free UDP port on 127.0.0.1 for the simulated boards to listen on."""
    return _free_udp_port


@pytest.fixture(scope="session")
def boards_and_driver(
    ros_graph: Any, ros_test_environment: dict[str, str]
) -> Callable[..., AbstractContextManager[Any]]:
    """``with boards_and_driver(log_name, **driver_parameters) as run``: the sim_hardware node on a free port and a
    stand-alone driver node linked to it (0.2 s silence and 0.5 s command rules unless given), both in the
    graph; on leaving, both must have exited cleanly."""
    from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes

    @contextmanager
    def run(log_name: str, **driver_parameters: Any) -> Iterator[SuiteRun]:
        port = _free_udp_port()
        driver = {"router_port": port, "board_silence_timeout_s": 0.2, "command_timeout_s": 0.5, **driver_parameters}
        specs = (
            NodeSpec("sim_hardware", "rh5_bringup", "sim_hardware_node", {"listen_port": port}),
            NodeSpec("driver", "rh5_bringup", "driver_node", driver),
        )
        log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / log_name
        with SuiteRun(Bringup("", specs), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as suite:
            assert wait_for_nodes(ros_graph, {"sim_hardware", "driver"}) == set()
            yield suite
        assert [p.process.returncode for p in suite.processes] == [0, 0]

    return run
