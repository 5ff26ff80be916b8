"""What this machine allows any 1 kHz loop: the floor under the control cycle's timing targets.

Runs a bare Python deadline loop (sleep to the deadline, then a 50 us spin; garbage collector frozen, memory
locked, SCHED_FIFO 50) in a child process, once without and once with the PM QoS request the control cycle
makes (``rh5_msgs_py.realtime.keep_cpus_awake``), each for ``--seconds``, optionally beside ``--burners``
CPU-burning processes. Prints rate, period jitter p99, the longest period and the periods over 2 ms, each as
a ratio to the real-time cycle issue's target. Whatever the bare loop misses, no control cycle on this machine
can hold: compare with ``bench/control_loop.py``.

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

import numpy as np

from rh5_msgs_py.realtime import keep_cpus_awake, lock_memory

TARGET_RATE_HZ = 999.5
TARGET_JITTER_P99_US = 100.0
TARGET_PERIOD_MAX_US = 2000.0
PERIOD_NS = 1_000_000
SPIN_NS = 50_000
BURN = "import time\nwhile True:\n    time.monotonic()\n"


def measure(seconds: float, keep_awake: bool) -> dict[str, float]:
    """The bare loop in this process: wake-up times over ``seconds``, summarised."""
    awake = keep_cpus_awake() if keep_awake else "not asked"
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
    lock_memory()
    gc.collect()
    gc.freeze()
    gc.disable()
    wakes = np.zeros(int(seconds * 1e9 / PERIOD_NS), dtype=np.int64)
    deadline = time.monotonic_ns() + PERIOD_NS
    misses = 0
    for i in range(len(wakes)):
        remaining = deadline - time.monotonic_ns()
        if remaining > 0:
            time.sleep(remaining / 1e9)
        wakes[i] = now = time.monotonic_ns()
        while time.monotonic_ns() < now + SPIN_NS:
            pass
        deadline += PERIOD_NS
        finished = time.monotonic_ns()
        if finished > deadline:  # skip lost ticks, as the suite's DeadlineLoop does
            missed = (finished - deadline) // PERIOD_NS + 1
            misses += missed
            deadline += missed * PERIOD_NS
    periods = np.diff(wakes) / 1e3
    return {
        "keep_awake": awake or "held",
        "rate_hz": (len(wakes) - 1) / ((wakes[-1] - wakes[0]) / 1e9),
        "jitter_p99_us": float(np.percentile(np.abs(periods - PERIOD_NS / 1e3), 99)),
        "period_max_us": float(periods.max()),
        "over_2ms": int((periods > TARGET_PERIOD_MAX_US).sum()),
        "misses": int(misses),
    }


def measure_floor(seconds: float, keep_awake: bool = True, cpu: int | None = None) -> dict[str, float]:
    """The bare loop in a child process (on ``cpu`` if given), summarised as ``measure`` does."""
    command = [sys.executable, __file__, "--child", "awake" if keep_awake else "plain", "--seconds", str(seconds)]
    child = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    if cpu is not None:
        os.sched_setaffinity(child.pid, {cpu})
    out, _ = child.communicate()
    if child.returncode != 0:
        raise RuntimeError(f"the bare loop failed (exit {child.returncode})")
    return json.loads(out)


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
    parser.add_argument("--child", choices=["plain", "awake"], help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(measure(args.seconds, args.child == "awake")))
        return
    burners = [subprocess.Popen([sys.executable, "-c", BURN]) for _ in range(args.burners)]
    try:
        for keep_awake in (False, True):
            result = measure_floor(args.seconds, keep_awake)
            print(
                f"bare loop, SCHED_FIFO 50, {args.seconds:g} s, {args.burners} burners, "
                f"PM QoS 0 us: {result['keep_awake']}"
            )
            print(_row("rate [Hz]", result["rate_hz"], TARGET_RATE_HZ, "Hz", higher_is_better=True))
            print(_row("jitter p99 [us]", result["jitter_p99_us"], TARGET_JITTER_P99_US, "us"))
            print(_row("longest period [us]", result["period_max_us"], TARGET_PERIOD_MAX_US, "us"))
            print(f"  {'periods over 2 ms':<26}{result['over_2ms']:10d}   target 0")
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()


if __name__ == "__main__":
    main()
