"""Fixtures shared by the integration tests (the session-wide rules are in the repository's conftest.py)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

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
