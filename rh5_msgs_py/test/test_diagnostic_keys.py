"""The /diagnostics names and keys keep their texts: bags, the report, the benchmarks and tools read them."""

from __future__ import annotations

from rh5_msgs_py import interfaces
from rh5_msgs_py.diagnostic_keys import (
    CONTROL_STATUS,
    DRIVER_STATUS,
    HARDWARE_ID,
    MAPPER_STATUS,
    PHYSICS_TASK,
    PLANNER_STATUS,
    STABILIZER_STATUS,
    ControlKeys,
    DriverKeys,
    LoopKeys,
    MapperKeys,
    StabilizerKeys,
    task_name,
    task_prefix,
)
from rh5_msgs_py.realtime import LatencyWindow, LoopStats, loop_stats_values


def test_status_names() -> None:
    assert (CONTROL_STATUS, DRIVER_STATUS, MAPPER_STATUS, STABILIZER_STATUS, PLANNER_STATUS) == (
        "rh5/control",
        "rh5/driver",
        "rh5/mapper",
        "rh5/stabilizer",
        "rh5/planner",
    )
    assert HARDWARE_ID == "rh5"
    assert task_name(interfaces.SIM_HARDWARE_NODE, PHYSICS_TASK) == "sim_hardware: physics"
    assert task_prefix(interfaces.STABILIZER_NODE) == "stabilizer:"


def test_stabilizer_driver_and_mapper_keys() -> None:
    assert (StabilizerKeys.STATE, StabilizerKeys.REASON) == ("state", "reason")
    assert StabilizerKeys.TRAJECTORY_DURATION_S == "trajectory_duration_s"
    assert StabilizerKeys.TRAJECTORY_REJECTED == "trajectory_rejected"
    assert StabilizerKeys.LOOP_ERROR == "loop_error"
    assert (DriverKeys.ESTOPPED, DriverKeys.SAFE_HOLD) == ("estopped", "safe_hold")
    assert DriverKeys.BOARD_ERRORS == "board_errors"
    assert DriverKeys.CLAMPED_PREFIX == MapperKeys.CLAMPED_PREFIX == "clamped."
    assert MapperKeys.REJECTED_PREFIX == "rejected."


def test_loop_and_control_keys() -> None:
    assert LoopKeys.PREFIX == "loop."
    assert (LoopKeys.REALTIME, LoopKeys.REALTIME_GRANTED) == ("loop.realtime", "loop.realtime_granted")
    assert LoopKeys.JITTER_HISTOGRAM == "loop.jitter_histogram"
    assert LoopKeys.gc_collections(2) == "loop.gc2_collections"
    assert LoopKeys.gc_pause(0, "p50_us") == "loop.gc0_p50_us"
    assert ControlKeys.telemetry_to_command("p99_us") == "latency.telemetry_to_command.p99_us"
    assert ControlKeys.cycle("p99_us") == "cycle.p99_us"
    assert ControlKeys.cycle("p50_us", "cpu") == "cycle.cpu.p50_us"
    assert ControlKeys.HELPERS_REALTIME == "helpers.realtime"
    assert ControlKeys.STREAMS_DROPPED == "streams.dropped"


def test_loop_values_are_the_loop_stats_under_their_old_keys() -> None:
    """``loop.<field>`` for every LoopStats field, rounded as ``as_dict`` rounds them."""
    stats = LoopStats(10, 999.123, 1000.456, 1010.0, 1200.0, 1.234, 9.876, 200.0, 3)
    assert loop_stats_values(stats) == {f"loop.{k}": v for k, v in stats.as_dict().items()}
    assert set(LatencyWindow().percentiles_us()) == {"p50_us", "p99_us", "max_us"}


def test_interfaces_re_exports_them() -> None:
    assert interfaces.STABILIZER_STATUS == STABILIZER_STATUS
    assert interfaces.LoopKeys is LoopKeys
