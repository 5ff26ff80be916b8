"""``rh5-plan --sweep`` without a solve: axes, grid validation, warm-start chains, the checkpoint. The real sweep on
Ray (local default, a two-node cluster, resume, a killed worker) is the integration test tests/test_sweep_ray.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rh5_planner.sweep.checkpoint import Checkpoint, CheckpointMismatchError
from rh5_planner.sweep.grid import Grid, GridError, parse_axis
from rh5_planner.sweep.point import PointOutcome, WarmStart

MOTION = "squat_with_5kg_weights"


def test_axes_parse_ranges_and_lists() -> None:
    assert parse_axis("payload_kg_per_hand=0:10:3").values == (0.0, 5.0, 10.0)
    assert parse_axis("knee:velocity=1,1.5,3").values == (1.0, 1.5, 3.0)
    assert parse_axis("knee:velocity=2:2:1").values == (2.0,)
    assert parse_axis("speed_m_s=0.1:0.3:3").values == (0.1, 0.2, 0.3)
    for bad in ("payload", "x=1:2", "x=a:2:3", "x=1:2:0", "x=1,1", "=1,2"):
        with pytest.raises(GridError):
            parse_axis(bad)


def test_grid_validates_keys_and_chains_warm_starts_along_the_last_axis() -> None:
    grid = Grid(MOTION, (parse_axis("payload_kg_per_hand=0,5"), parse_axis("knee:velocity=1:4:4")), {}, chain=2)
    points = grid.points()
    assert [p.id for p in points][:3] == ["p0000", "p0001", "p0002"]
    # chains of two along knee:velocity: every other point starts cold, the rest from the point before
    assert [p.warm_from for p in points] == [None, 0, None, 2, None, 4, None, 6]
    assert points[5].values == {"payload_kg_per_hand": 5.0, "knee:velocity": 2.0}
    assert points[5].limit_scale().entries == (("knee", "velocity", 2.0),)
    walk = Grid("walk_with_5kg_weights", (parse_axis("speed_m_s=0.4,0.5"),), {})
    assert walk.motion_of(walk.points()[1]).length_m == pytest.approx(0.75)  # 0.5 m/s over the walk's 1.5 s
    # along a motion parameter the dynamics change: no warm starts there
    assert [p.warm_from for p in Grid(MOTION, (parse_axis("payload_kg_per_hand=0,5"),), {}).points()] == [None, None]
    assert [p.warm_from for p in Grid(MOTION, grid.axes, {}, warm_start=False).points()] == [None] * 8
    for axes in (("speed_m_s=0.3,0.4",), ("no_such_key=1,2",), ("knee:speed=1,2",), ("nojoint:velocity=1,2",)):
        with pytest.raises(GridError):
            Grid(MOTION, tuple(parse_axis(a) for a in axes), {}).points()
    with pytest.raises(GridError):  # an invalid point is refused before anything is solved
        Grid(MOTION, (parse_axis("com_range_m=0.2,0.5"),), {}).points()


def test_checkpoint_keeps_rows_and_solutions_and_ignores_a_half_written_line(tmp_path: Path) -> None:
    description = {"grid": {"motion": MOTION}, "solver": {"max_iterations": 10}}
    checkpoint = Checkpoint(tmp_path, description)
    warm = WarmStart(np.arange(6.0).reshape(2, 3), (np.array([1.0, 2.0]), np.zeros(0), np.array([3.0])))
    checkpoint.record(PointOutcome({"point": "p0000", "status": "feasible"}, warm))
    checkpoint.record(PointOutcome({"point": "p0001", "status": "failed"}))
    with (tmp_path / "points.jsonl").open("a") as file:
        file.write('{"point": "p0002", "sta')  # killed while writing
    again = Checkpoint(tmp_path, description)
    assert set(again.rows) == {"p0000", "p0001"}
    assert set(again.done()) == {"p0000"}  # a failed point is solved again on resume
    loaded = again.warm_start("p0000")
    assert loaded is not None
    np.testing.assert_array_equal(loaded.xs, warm.xs)
    assert [u.tolist() for u in loaded.us] == [[1.0, 2.0], [], [3.0]]
    assert again.warm_start("p0001") is None
    with pytest.raises(CheckpointMismatchError):
        Checkpoint(tmp_path, {**description, "solver": {"max_iterations": 20}})
    assert not Checkpoint(tmp_path, {**description, "solver": {}}, restart=True).rows


def test_the_sweep_command_gives_the_callers_sigint_handler_back(tmp_path: Path) -> None:
    """A sweep installs Python's KeyboardInterrupt handler while it solves (so that Ctrl-C interrupts it also where
    SIGINT was inherited ignored) and restores the caller's when it ends: one cheap point, solved in-process."""
    import io
    import signal

    from rh5_planner.plan_cli import main

    def callers_handler(_signum: int, _frame: object) -> None:
        """Stands for an embedding program's own handler."""

    previous = signal.signal(signal.SIGINT, callers_handler)
    try:
        cheap = ["--set", "total_time_s=0.6", "--set", "hold_s=0.1", "--set", "com_range_m=0.1"]
        argv = ["--sweep", "squat_with_5kg_weights", "payload_kg_per_hand=0", "--engine", "serial", *cheap]
        argv += ["--max-iterations", "5", "--output-dir", str(tmp_path), "--no-figures"]
        err = io.StringIO()
        assert main(argv, out=io.StringIO(), err=err) in {0, 1}, err.getvalue()
        assert "engine: serial (this process)" in err.getvalue()
        assert signal.getsignal(signal.SIGINT) is callers_handler
    finally:
        signal.signal(signal.SIGINT, previous)
