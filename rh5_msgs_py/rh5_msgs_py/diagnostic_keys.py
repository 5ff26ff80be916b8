"""The /diagnostics status names and value keys that another process reads: one text for writer and reader.

The nodes write these keys; ``rh5 experiment`` follows the stabilizer through them, the report and the benchmarks
read the loop timing and the faults from recorded bags. Bags, tools and tests depend on the texts: never change
one (``rh5_msgs_py/test/test_diagnostic_keys.py`` pins them). Re-exported by :mod:`rh5_msgs_py.interfaces`.
"""

from __future__ import annotations

from typing import Final, Literal

HARDWARE_ID: Final = "rh5"
"""``hardware_id`` of every status of the suite."""

CONTROL_STATUS: Final = "rh5/control"
DRIVER_STATUS: Final = "rh5/driver"
MAPPER_STATUS: Final = "rh5/mapper"
STABILIZER_STATUS: Final = "rh5/stabilizer"
PLANNER_STATUS: Final = "rh5/planner"
"""The planner's progress status (on ``planner/progress``)."""

PHYSICS_TASK: Final = "physics"
"""The simulated hardware's physics task: ``sim_hardware: physics``."""


def task_name(node: str, task: str) -> str:
    """The name of ``task`` of ``node`` as diagnostic_updater names it: ``"<node>: <task>"``."""
    return f"{node}: {task}"


def task_prefix(node: str) -> str:
    """What the names of every task status of ``node`` start with."""
    return f"{node}:"


Percentile = Literal["p50_us", "p99_us", "max_us"]
"""The statistics of a duration window (``realtime.LatencyWindow.percentiles_us``), the last part of its keys."""


class StabilizerKeys:
    """``rh5/stabilizer``: the state machine and its trajectory (the experiment runner and the report follow them)."""

    STATE: Final = "state"
    REASON: Final = "reason"
    """Why the state last changed (e.g. 'trajectory finished', 'hold requested')."""
    TRAJECTORY_DURATION_S: Final = "trajectory_duration_s"
    """Duration of the trajectory it holds, or 'none'."""
    TRAJECTORY_REJECTED: Final = "trajectory_rejected"
    """Why the last trajectory offered was rejected ('' when it was not)."""
    LOOP_ERROR: Final = "loop_error"


class DriverKeys:
    """``rh5/driver``: safety state and board faults."""

    ESTOPPED: Final = "estopped"
    SAFE_HOLD: Final = "safe_hold"
    BOARD_ERRORS: Final = "board_errors"
    CLAMPED_PREFIX: Final = "clamped."
    """``clamped.<actuator>``: commands clamped to the actuator's limits."""


class MapperKeys:
    """``rh5/mapper``: maps refused and setpoints clamped, per topic or actuator."""

    REJECTED_PREFIX: Final = "rejected."
    CLAMPED_PREFIX: Final = "clamped."


class LoopKeys:
    """``loop.*``: a 1 kHz loop's timing, real-time grant and garbage collection
    (``rh5_msgs_py.realtime.LoopThread.diagnostics``; on ``rh5/control``, and on ``rh5/driver`` and
    ``rh5/stabilizer`` when they run on their own)."""

    PREFIX: Final = "loop."
    CYCLES: Final = "loop.cycles"
    RATE_HZ: Final = "loop.rate_hz"
    PERIOD_P50_US: Final = "loop.period_p50_us"
    PERIOD_P99_US: Final = "loop.period_p99_us"
    PERIOD_MAX_US: Final = "loop.period_max_us"
    JITTER_P50_US: Final = "loop.jitter_p50_us"
    JITTER_P99_US: Final = "loop.jitter_p99_us"
    JITTER_MAX_US: Final = "loop.jitter_max_us"
    DEADLINE_MISSES: Final = "loop.deadline_misses"
    REALTIME: Final = "loop.realtime"
    """What the OS granted the loop thread, in words."""
    REALTIME_GRANTED: Final = "loop.realtime_granted"
    JITTER_HISTOGRAM: Final = "loop.jitter_histogram"
    """Run-long jitter histogram (``realtime.jitter_histogram_text``)."""

    @staticmethod
    def gc_collections(generation: int) -> str:
        """Collections of ``generation`` in the loop's slack since start."""
        return f"loop.gc{generation}_collections"

    @staticmethod
    def gc_pause(generation: int, stat: Percentile) -> str:
        """A statistic of the pauses of ``generation``'s collections."""
        return f"loop.gc{generation}_{stat}"


class ControlKeys:
    """``rh5/control``: the control cycle's latency, work per stage and its publishing child (besides ``loop.*``)."""

    HELPERS_REALTIME: Final = "helpers.realtime"
    STREAMS_DROPPED: Final = "streams.dropped"
    """Cycle samples the publishing child could not take (a full pipe)."""

    @staticmethod
    def telemetry_to_command(stat: Percentile) -> str:
        """Latency from the boards' telemetry to the command written from it."""
        return f"latency.telemetry_to_command.{stat}"

    @staticmethod
    def cycle(stat: Percentile, stage: str | None = None) -> str:
        """Duration of the cycle's work, or of one ``stage`` of it (cpu, read, to_joints, stabilize, ...)."""
        return f"cycle.{stat}" if stage is None else f"cycle.{stage}.{stat}"
