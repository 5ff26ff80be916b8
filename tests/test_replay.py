"""In-process replays of a planned squat on PyBullet (rh5_bringup.sim.replay): the paper's joint-PD setup and
the suite's board chain keep the floating base where the plan puts it (quasi-static motion: a few mm)."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_bringup.sim.replay import replay
from rh5_msgs_py.trajectory_file import TrajectoryData
from rh5_planner.motions import get_motion
from rh5_planner.ocp import solve


@pytest.fixture(scope="module")
def one_squat() -> TrajectoryData:
    result = solve(get_motion("fast_squats", {"n_squats": 1, "total_time_s": 2.3}))
    assert result.converged
    return result.to_trajectory_data()


@pytest.mark.parametrize("controller", ["rigid_pd", "boards"])
def test_a_planned_squat_keeps_the_base_on_the_plan(one_squat: TrajectoryData, controller: str) -> None:
    result = replay(one_squat, controller)  # type: ignore[arg-type]
    assert result.times[-1] == pytest.approx(one_squat.times[-1] - one_squat.times[0])
    extent_mm = np.abs(result.deviation_range).max(axis=1) * 1e3  # x, y, z
    assert (extent_mm < 10.0).all(), extent_mm
    assert result.max_sole_tilt < np.radians(1.0)  # both feet stay flat: no rolling over an edge


def test_an_unknown_controller_is_refused(one_squat: TrajectoryData) -> None:
    with pytest.raises(ValueError, match="controller must be one of"):
        replay(one_squat, "torque_magic")  # type: ignore[arg-type]
