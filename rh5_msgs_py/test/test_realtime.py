"""The shared 1 kHz machinery: latest-value slot, loop statistics, the deadline loop."""

from __future__ import annotations

import gc
import itertools
import os
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest

from rh5_msgs_py.realtime import (
    GC_OVERDUE,
    JITTER_EDGES_US,
    DeadlineLoop,
    GarbageCollection,
    LatencyWindow,
    LatestValue,
    LoopTimer,
    jitter_percentile_us,
)


def test_latest_value_keeps_the_newest_and_its_stamp() -> None:
    slot: LatestValue[tuple[int, ...]] = LatestValue()
    assert slot.try_get() == (None, 0, 0)
    assert slot.age_ns() is None
    slot.set((1, 2), stamp_ns=100)
    slot.set((3, 4), stamp_ns=250)
    assert slot.try_get() == ((3, 4), 250, 2)
    assert slot.age_ns(now_ns=1250) == 1000


def test_latest_value_reader_never_blocks_on_a_writer() -> None:
    slot: LatestValue[int] = LatestValue()
    slot.set(7, stamp_ns=5)
    with slot._lock:  # another writer in the middle of set()
        start = time.perf_counter()
        assert slot.try_get() == (7, 5, 1)  # the last complete write, not "nothing this tick"
        assert time.perf_counter() - start < 0.01


def test_latest_value_readers_see_every_write_whole_under_contention() -> None:
    slot: LatestValue[tuple[int, int]] = LatestValue()
    stop = threading.Event()

    def writer() -> None:
        n = 0
        while not stop.is_set():
            n += 1
            slot.set((n, -n), stamp_ns=n)

    threads = [threading.Thread(target=writer) for _ in range(2)]
    for thread in threads:
        thread.start()
    try:
        last_version = 0
        for _ in range(20_000):
            value, stamp, version = slot.try_get()
            assert version >= last_version
            if version:
                assert value is not None
                assert value == (stamp, -stamp)  # never a torn or missing value
            last_version = version
    finally:
        stop.set()
        for thread in threads:
            thread.join()


def test_loop_timer_statistics_from_synthetic_wake_ups() -> None:
    timer = LoopTimer(period_ns=1_000_000, window=10)
    wakes = [0, 1_000_000, 2_000_000, 3_050_000, 4_000_000, 5_000_000]
    for wake in wakes:
        timer.record(wake)
    stats = timer.stats()
    assert stats.cycles == 6
    assert stats.rate_hz == pytest.approx(1000.0)
    assert stats.period_max_us == pytest.approx(1050.0)
    assert stats.jitter_max_us == pytest.approx(50.0)
    assert stats.jitter_p50_us == pytest.approx(0.0)


def test_loop_timer_window_keeps_only_the_latest_cycles() -> None:
    timer = LoopTimer(period_ns=1_000_000, window=3)
    for k in range(10):
        timer.record(k * 2_000_000 if k < 6 else 12_000_000 + (k - 6) * 1_000_000)
    assert timer.stats().rate_hz == pytest.approx(1000.0)


def test_the_run_long_jitter_histogram_bins_every_period_once() -> None:
    """Periods of 1000, 1005, 1040, 2500 (a miss) and 1000 us, read once per window: each lands in its bucket once,
    also when stats() is called again without new wake-ups; the run's p99 and its periods over 2 ms follow."""
    timer = LoopTimer(period_ns=1_000_000, window=3)
    wake = 0
    for period_us in (1000, 1005, 1040, 2500, 1000):
        timer.record(wake)
        wake += period_us * 1000
        timer.stats()
    timer.record(wake)
    timer.stats()
    timer.stats()
    counts = timer.jitter_counts
    assert counts.sum() == 5
    expected = {0: 3, JITTER_EDGES_US.index(40): 1, JITTER_EDGES_US.index(2000): 1}  # <= 10, (30, 40], (1000, 2000]
    assert {int(i): int(c) for i, c in enumerate(counts) if c} == expected
    assert jitter_percentile_us(counts, 50) == 10.0
    assert jitter_percentile_us(counts, 99) == 2000.0
    assert int(counts[JITTER_EDGES_US.index(1000) + 1 :].sum()) == 1  # one period over 2 ms
    assert np.isnan(jitter_percentile_us(np.zeros_like(counts), 99))


def test_deadline_loop_runs_at_its_rate_with_now_and_period() -> None:
    calls: list[tuple[int, int]] = []
    loop = DeadlineLoop(1000.0, lambda now, period: calls.append((now, period)))
    loop.start()
    time.sleep(0.5)
    loop.stop()
    loop.stop()  # idempotent
    assert not loop.running
    assert 250 <= len(calls) <= 510  # never faster than its rate; on a busy 2-core machine it may skip ticks
    assert {period for _, period in calls} == {1_000_000}
    stats = loop.stats()
    assert stats.cycles == len(calls)
    assert stats.period_p50_us == pytest.approx(1000.0, abs=100.0)  # skipped ticks show as misses, not drift


def test_overrunning_steps_are_counted_and_skipped_not_burst() -> None:
    done = threading.Event()
    calls: list[int] = []

    def slow(now: int, _period: int) -> None:
        calls.append(now)
        if len(calls) == 5:
            time.sleep(0.0105)  # overrun by ten and a half periods
        if len(calls) >= 20:
            done.set()

    loop = DeadlineLoop(1000.0, slow)
    loop.start()
    assert done.wait(2.0)
    loop.stop()
    assert loop.stats().deadline_misses >= 10
    gaps = [b - a for a, b in itertools.pairwise(calls[5:13])]
    # No catch-up burst after the overrun (that would be ten gaps near zero); one late wake-up of a loaded
    # machine may shorten one gap (seen in CI: 255 us after a call that ran 750 us late).
    assert sum(gap < 500_000 for gap in gaps) <= 1, gaps


def test_rate_must_be_positive() -> None:
    with pytest.raises(ValueError, match="rate_hz must be positive"):
        DeadlineLoop(0.0, lambda _now, _period: None)


@pytest.fixture
def collector() -> Iterator[type[GarbageCollection]]:
    """Automatic collection off (as under a real-time loop) with the per-generation cost estimates restored after."""
    saved, enabled = list(GarbageCollection._cost_ns), gc.isenabled()
    gc.disable()
    try:
        yield GarbageCollection
    finally:
        GarbageCollection._cost_ns[:] = saved
        if enabled:
            gc.enable()


def _young_garbage(n: int) -> list[list[int]]:
    return [[k] for k in range(n)]  # tracked containers: each counts as an allocation for generation 0


def test_a_collection_runs_only_when_its_measured_cost_fits_the_slack(
    collector: type[GarbageCollection],
) -> None:
    """A young collection costs tens of us; one estimated at 500 us is not started with 300 us of slack
    (it would overrun the deadline), but is with 700 us, and its measured time then replaces the estimate."""
    windows = [LatencyWindow(10) for _ in range(3)]
    gc.collect()
    keep = _young_garbage(gc.get_threshold()[0] + 10)
    collector._cost_ns[:] = [500_000.0, 1e9, 1e9]
    collector.collect_in_slack(300_000, windows)
    assert [w.count for w in windows] == [0, 0, 0]
    assert gc.get_count()[0] > gc.get_threshold()[0]
    collector.collect_in_slack(700_000, windows)
    assert [w.count for w in windows] == [1, 0, 0]
    assert gc.get_count()[0] < gc.get_threshold()[0]
    assert collector._cost_ns[0] < 500_000.0  # measured, decayed from the first guess
    del keep


def test_young_garbage_far_overdue_is_collected_even_without_slack(collector: type[GarbageCollection]) -> None:
    """Memory must not grow without bound when no cycle ever has the slack: past GC_OVERDUE thresholds the
    young generation is collected anyway."""
    windows = [LatencyWindow(10) for _ in range(3)]
    gc.collect()
    collector._cost_ns[:] = [1e9, 1e9, 1e9]
    keep = _young_garbage(gc.get_threshold()[0] * 2)
    collector.collect_in_slack(0, windows)
    assert windows[0].count == 0
    keep += _young_garbage(gc.get_threshold()[0] * GC_OVERDUE)
    collector.collect_in_slack(0, windows)
    assert windows[0].count == 1
    del keep


_PIN_SCRIPT = """
import json, os, sys, threading
from pathlib import Path
from rh5_msgs_py.realtime import pin_process
started = threading.Event()
threading.Thread(target=started.wait, daemon=True).start()  # a thread that exists before the call
chosen = pin_process([int(sys.argv[1])])
later = threading.Thread(target=started.wait, daemon=True)  # and one started after it
later.start()
tasks = [int(t.name) for t in Path("/proc/self/task").iterdir()]
print(json.dumps({"chosen": chosen, "threads": [sorted(os.sched_getaffinity(t)) for t in tasks]}))
started.set()
"""


def test_pin_process_puts_every_thread_on_the_chosen_cpu_counted_from_the_end() -> None:
    """In a child process (pinning pytest would slow the rest of the run): -1 is the last CPU the process may use,
    for the threads that existed and those started after; an index the machine does not have is refused."""
    import json
    import subprocess
    import sys

    allowed = sorted(os.sched_getaffinity(0))
    out = subprocess.run([sys.executable, "-c", _PIN_SCRIPT, "-1"], capture_output=True, text=True, check=True)
    result = json.loads(out.stdout)
    assert result["chosen"] == [allowed[-1]]
    assert len(result["threads"]) >= 3
    assert all(cpus == [allowed[-1]] for cpus in result["threads"]), result
    bad = subprocess.run(
        [sys.executable, "-c", _PIN_SCRIPT, str(len(allowed))], capture_output=True, text=True, check=False
    )
    assert bad.returncode != 0
    assert f"CPU index {len(allowed)}: this process may use {len(allowed)} CPUs" in bad.stderr


_AWAKE_SCRIPT = """
import sys
from rh5_msgs_py.realtime import keep_cpus_awake
print(repr(keep_cpus_awake()), flush=True)
sys.stdin.readline()  # holds the request until the test lets go
"""


def _cpu_dma_latency_us() -> int:
    """The kernel's current PM QoS wake-up latency bound (the strictest request of all processes)."""
    from rh5_msgs_py.realtime import CPU_DMA_LATENCY

    return int.from_bytes(CPU_DMA_LATENCY.read_bytes()[:4], sys.byteorder, signed=True)


@pytest.mark.skipif(not os.access("/dev/cpu_dma_latency", os.W_OK), reason="needs write access to PM QoS")
def test_keep_cpus_awake_holds_zero_latency_for_the_life_of_the_process() -> None:
    """In a child process (the request would otherwise last for the rest of the run): the kernel's bound is 0 us
    while the child holds it and returns to what it was once the child exits."""
    import subprocess

    before = _cpu_dma_latency_us()
    child = subprocess.Popen(
        [sys.executable, "-c", _AWAKE_SCRIPT], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        assert child.stdout.readline().strip() == "''"  # held
        assert _cpu_dma_latency_us() == 0
    finally:
        child.communicate("\n", timeout=30)
    assert child.returncode == 0
    deadline = time.monotonic() + 10.0  # another process of the run may hold its own request for a moment
    while _cpu_dma_latency_us() != before and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _cpu_dma_latency_us() == before


def test_keep_cpus_awake_refused_says_why_and_the_grant_still_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the file (or the right to write it) nothing is raised: the grant runs on and names why."""
    from pathlib import Path

    from rh5_msgs_py import realtime
    from rh5_msgs_py.realtime import scheduling  # where keep_cpus_awake keeps its request

    monkeypatch.setattr(scheduling, "CPU_DMA_LATENCY", Path("/nonexistent/cpu_dma_latency"))
    monkeypatch.setattr(scheduling, "_idle_request", None)
    reason = realtime.keep_cpus_awake()
    assert reason == "/nonexistent/cpu_dma_latency: No such file or directory"
    grant = realtime.RealtimeGrant(50, 50, True, idle_wakeup=reason)
    assert grant.describe() == f"SCHED_FIFO 50, memory locked, CPU idle not limited ({reason})"
    assert realtime.RealtimeGrant(50, 50, True).describe() == "SCHED_FIFO 50, memory locked, CPUs kept from deep idle"


_HEAP_SCRIPT = """
import resource, sys
from rh5_msgs_py.realtime import keep_heap

def rss_mb():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * resource.getpagesize() / 2**20

start = rss_mb()
kept = keep_heap(48 * 2**20) if sys.argv[1] == "kept" else None
reserved = rss_mb()
block = bytearray(32 * 2**20)
del block
print(kept, round(reserved - start), round(rss_mb() - reserved))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_keep_heap_faults_a_reserve_in_and_serves_big_blocks_from_it() -> None:
    """In child processes (the tuning lasts for the process): with glibc's defaults a freed 32 MB block goes back
    to the OS, so the next one is faulted in afresh; with a kept heap the reserve stays resident, and the block
    comes from it without growing the process."""
    import subprocess

    def run(mode: str) -> list[str]:
        out = subprocess.run([sys.executable, "-c", _HEAP_SCRIPT, mode], capture_output=True, text=True, check=True)
        return out.stdout.split()

    kept, reserved, grown = run("kept")
    assert kept == "True"
    assert int(reserved) >= 46  # the 48 MB reserve, resident
    assert int(grown) <= 2  # the 32 MB block came from it, and freeing it kept it
    _, reserved, grown = run("default")
    assert int(reserved) <= 2
    assert int(grown) <= 2  # glibc mapped the block for itself and unmapped it when freed
