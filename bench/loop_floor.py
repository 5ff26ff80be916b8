"""What this machine allows any 1 kHz loop: the floor under the control cycle's timing targets.

Runs a bare Python deadline loop (sleep to the deadline, then a 50 us spin; garbage collector frozen, memory
locked, SCHED_FIFO 50) in a child process, once without and once with the PM QoS request the control cycle
makes (``rh5_msgs_py.realtime.keep_cpus_awake``), each for ``--seconds``, optionally beside ``--burners``
CPU-burning processes. Prints rate, period jitter p99, the longest period and the periods over 2 ms, each as
a ratio to the real-time cycle issue's target. Whatever the bare loop misses, no control cycle on this machine
can hold: compare with ``bench/control_loop.py``.

It also reads its CPU's steal time (``/proc/stat``: time the hypervisor ran something else on this virtual CPU) at
every wake-up, and prints how much of it fell into the periods over 2 ms against their excess over 1 ms: where the
two are equal, the host, not this guest, took the CPU away (2026-11-26: 300 ms of steal in periods with 316 ms of
excess, 101 of them in 20 s).

    .venv/bin/python bench/loop_floor.py [--seconds 60] [--burners 0]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from rh5_msgs_py.realtime import keep_cpus_awake, lock_memory

TARGET_RATE_HZ = 999.5
TARGET_JITTER_P99_US = 100.0
TARGET_PERIOD_MAX_US = 2000.0
PERIOD_NS = 1_000_000
SPIN_NS = 50_000
BURN = "import time\nwhile True:\n    time.monotonic()\n"


@contextmanager
def cpu_burners(count: int) -> Iterator[None]:
    """``count`` processes that spin on the CPU at normal priority (other work on the machine) while inside."""
    burners = [subprocess.Popen([sys.executable, "-c", BURN], stdout=subprocess.DEVNULL) for _ in range(count)]
    try:
        yield
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()


def steal_ms(cpu: int) -> int:
    """Steal time of ``cpu`` since boot in ms (/proc/stat counts it in 10 ms ticks)."""
    prefix = f"cpu{cpu} "
    with open("/proc/stat") as stat:
        for line in stat:
            if line.startswith(prefix):
                return int(line.split()[8]) * 10
    raise ValueError(f"no CPU {cpu} in /proc/stat")


def measure(seconds: float, keep_awake: bool, cpu: int) -> dict[str, float]:
    """The bare loop in this process, on ``cpu``: wake-up times and steal over ``seconds``, summarised."""
    os.sched_setaffinity(0, {cpu})
    awake = keep_cpus_awake() if keep_awake else "not asked"
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
    lock_memory()
    gc.collect()
    gc.freeze()
    gc.disable()
    wakes = np.zeros(int(seconds * 1e9 / PERIOD_NS), dtype=np.int64)
    steals = np.zeros(len(wakes), dtype=np.int64)
    deadline = time.monotonic_ns() + PERIOD_NS
    misses = 0
    for i in range(len(wakes)):
        remaining = deadline - time.monotonic_ns()
        if remaining > 0:
            time.sleep(remaining / 1e9)
        wakes[i] = now = time.monotonic_ns()
        steals[i] = steal_ms(cpu)  # part of the 50 us of work
        while time.monotonic_ns() < now + SPIN_NS:
            pass
        deadline += PERIOD_NS
        finished = time.monotonic_ns()
        if finished > deadline:  # skip lost ticks, as the suite's DeadlineLoop does
            missed = (finished - deadline) // PERIOD_NS + 1
            misses += missed
            deadline += missed * PERIOD_NS
    periods = np.diff(wakes) / 1e3
    long = periods > TARGET_PERIOD_MAX_US
    return {
        "keep_awake": awake or "held",
        "rate_hz": (len(wakes) - 1) / ((wakes[-1] - wakes[0]) / 1e9),
        "jitter_p99_us": float(np.percentile(np.abs(periods - PERIOD_NS / 1e3), 99)),
        "period_max_us": float(periods.max()),
        "over_2ms": int((periods > TARGET_PERIOD_MAX_US).sum()),
        "misses": int(misses),
        "long_excess_ms": float((periods[long] - PERIOD_NS / 1e3).sum() / 1e3),
        "long_steal_ms": int(np.diff(steals)[long].sum()),
        "steal_ms": int(steals[-1] - steals[0]),
    }


def measure_floor(seconds: float, keep_awake: bool = True, cpu: int | None = None) -> dict[str, float]:
    """The bare loop in a child process on ``cpu`` (default: this process's last allowed CPU), summarised as
    ``measure`` does."""
    cpu = sorted(os.sched_getaffinity(0))[-1] if cpu is None else cpu
    mode = "awake" if keep_awake else "plain"
    command = [sys.executable, __file__, "--child", mode, "--seconds", str(seconds), "--cpu", str(cpu)]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    out, _ = child.communicate()
    if child.returncode != 0:
        raise RuntimeError(f"the bare loop failed (exit {child.returncode})")
    return json.loads(out)


def steal_line(result: dict[str, float]) -> str:
    """The periods over 2 ms against the hypervisor's steal time in them (10 ms resolution)."""
    return (
        f"  {'steal in those periods':<26}{result['long_steal_ms']:10d}   ms, against their excess over 1 ms of "
        f"{result['long_excess_ms']:.0f} ms (steal over the whole run {result['steal_ms']} ms)"
    )


def _row(label: str, value: float, target: float, unit: str, higher_is_better: bool = False) -> str:
    ratio = value / target
    ok = value >= target if higher_is_better else value <= target
    sign = ">=" if higher_is_better else "<="
    verdict = "PASS" if ok else "MISS"
    return f"  {label:<26}{value:10.2f}   target {sign} {target:g} {unit:<3} ratio {ratio:6.3f}  {verdict}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--burners", type=int, default=0)
    parser.add_argument("--cpu", type=int, help="the CPU of the loop (default: the last this process may use)")
    parser.add_argument("--child", choices=["plain", "awake"], help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(measure(args.seconds, args.child == "awake", args.cpu)))
        return
    with cpu_burners(args.burners):
        for keep_awake in (False, True):
            result = measure_floor(args.seconds, keep_awake, args.cpu)
            print(
                f"bare loop, SCHED_FIFO 50, {args.seconds:g} s, {args.burners} burners, "
                f"PM QoS 0 us: {result['keep_awake']}"
            )
            print(_row("rate [Hz]", result["rate_hz"], TARGET_RATE_HZ, "Hz", higher_is_better=True))
            print(_row("jitter p99 [us]", result["jitter_p99_us"], TARGET_JITTER_P99_US, "us"))
            print(_row("longest period [us]", result["period_max_us"], TARGET_PERIOD_MAX_US, "us"))
            print(f"  {'periods over 2 ms':<26}{result['over_2ms']:10d}   target 0")
            print(steal_line(result))


if __name__ == "__main__":
    main()
