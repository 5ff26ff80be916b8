"""The 1 kHz machinery shared by the control cycle, the driver, the stabilizer and the simulated boards.

rclpy timers drop ticks at 1 kHz here (design/ros2_wheels.md, 3d), so each periodic loop
runs in its own thread on absolute deadlines in integer nanoseconds. A loop given a real-time
priority asks for ``SCHED_FIFO`` for its thread only, locks the process's memory, keeps the CPUs
out of deep idle states and keeps the garbage collector out of its cycles (``request_realtime``,
``GarbageCollection``); under ``SCHED_FIFO`` a plain sleep to the deadline wakes within microseconds.
Without it (refused by the OS, or priority 0) the loop sleeps until shortly before the deadline and
spins the rest (``time.sleep`` alone overshoots by 50-100 us there). ROS callbacks hand data to the loop
through a ``LatestValue``: one slot that the loop reads without ever waiting for a writer; the
loop hands its topics to a ``RealtimePublisher``, whose thread publishes them and which drops a
sample rather than make the loop wait.

The package, one job a module: ``loops`` (LoopThread, DeadlineLoop), ``timing`` (LoopTimer, LoopStats,
LatencyWindow, the jitter histogram), ``scheduling`` (what is asked of the OS), ``collector`` (the garbage
collector kept out of the cycles) and ``handoff`` (LatestValue, RealtimePublisher). Every name is re-exported here.
"""

from __future__ import annotations

from rh5_msgs_py.realtime.collector import GC_COST_DECAY, GC_FIRST_COST_NS, GC_MARGIN_NS, GC_OVERDUE, GarbageCollection
from rh5_msgs_py.realtime.handoff import LatestValue, RealtimePublisher
from rh5_msgs_py.realtime.loops import GIL_SWITCH_INTERVAL_S, SPIN_NS, DeadlineLoop, LoopThread
from rh5_msgs_py.realtime.scheduling import (
    CPU_DMA_LATENCY,
    HEAP_RESERVE_BYTES,
    RTPRIO_FIX,
    TIMER_SLACK_NS,
    RealtimeGrant,
    keep_cpus_awake,
    keep_heap,
    lock_memory,
    pin_process,
    request_realtime,
    set_timer_slack,
)
from rh5_msgs_py.realtime.timing import (
    JITTER_EDGES_US,
    STATS_WINDOW,
    LatencyWindow,
    LoopStats,
    LoopTimer,
    jitter_above_us,
    jitter_histogram_text,
    jitter_percentile_us,
    loop_stats_values,
    parse_jitter_histogram,
)

__all__ = [
    "CPU_DMA_LATENCY",
    "GC_COST_DECAY",
    "GC_FIRST_COST_NS",
    "GC_MARGIN_NS",
    "GC_OVERDUE",
    "GIL_SWITCH_INTERVAL_S",
    "HEAP_RESERVE_BYTES",
    "JITTER_EDGES_US",
    "RTPRIO_FIX",
    "SPIN_NS",
    "STATS_WINDOW",
    "TIMER_SLACK_NS",
    "DeadlineLoop",
    "GarbageCollection",
    "LatencyWindow",
    "LatestValue",
    "LoopStats",
    "LoopThread",
    "LoopTimer",
    "RealtimeGrant",
    "RealtimePublisher",
    "jitter_above_us",
    "jitter_histogram_text",
    "jitter_percentile_us",
    "keep_cpus_awake",
    "keep_heap",
    "lock_memory",
    "loop_stats_values",
    "parse_jitter_histogram",
    "pin_process",
    "request_realtime",
    "set_timer_slack",
]
