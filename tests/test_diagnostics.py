"""/diagnostics in diagnostic_updater's layout, against real processes with injected faults.

The driver (its own 1 kHz loop) talks to the simulated boards; the test silences one board through the
simulation's fault parameter and asks the driver's loop for more than the machine can give (5 kHz), then reads
the per-component statuses: a silent board is ERROR, deadline misses are WARN, the other boards stay OK.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from typing import Any

import pytest

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import Level, diagnostics_from_msg
from rh5_msgs_py.names import ACTUATOR_NAMES

pytestmark = pytest.mark.ros

SILENT = "LLKnee_Act1"


class Statuses:
    """The latest status of every name seen on /diagnostics."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray

        self.node = node
        self.latest: dict[str, Any] = {}
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on, interfaces.EVENT_QOS)

    def _on(self, msg: Any) -> None:
        for status in diagnostics_from_msg(msg):
            self.latest[status.name] = status

    def wait_for(self, name: str, level: Level, timeout_s: float = 15.0) -> Any:
        import rclpy

        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            status = self.latest.get(name)
            if status is not None and status.level == level:
                return status
        seen = self.latest.get(name)
        pytest.fail(f"{name}: no {level.name} within {timeout_s} s; last {seen}")
        return None


@pytest.fixture(scope="module")
def suite(ros_graph: Any, boards_and_driver: Callable[..., AbstractContextManager[Any]]) -> Iterator[Statuses]:
    statuses = Statuses(ros_graph)
    with boards_and_driver("diagnostics", rate_hz=5000.0):
        yield statuses


def test_every_board_has_its_own_status_and_answers(suite: Statuses) -> None:
    for name in ACTUATOR_NAMES:
        suite.wait_for(f"driver: board {name}", Level.OK)
    assert suite.wait_for("driver: safety", Level.OK).message == "boards hold"
    assert suite.latest["sim_hardware: boards"].level == Level.OK
    assert "rh5/driver" in suite.latest  # the summary status the report reads stays


def test_deadline_misses_warn(suite: Statuses) -> None:
    status = suite.wait_for("driver: loop", Level.WARN)
    assert status.message == "deadline misses"
    assert int(status.values["new_deadline_misses"]) > 0


def test_a_silent_board_is_an_error_and_the_others_stay_ok(suite: Statuses, ros_graph: Any) -> None:
    from test_driver_sim import set_parameters

    set_parameters(ros_graph, "sim_hardware", silent_boards=[SILENT])
    status = suite.wait_for(f"driver: board {SILENT}", Level.ERROR)
    assert status.message == "silent"
    safety = suite.wait_for("driver: safety", Level.ERROR)
    assert safety.message == "safe hold"
    assert SILENT in safety.values["reason"]
    assert suite.latest["driver: board LRKnee_Act1"].level == Level.OK
    set_parameters(ros_graph, "sim_hardware", silent_boards=[])
    suite.wait_for(f"driver: board {SILENT}", Level.OK)
