"""Cost of one 1 ms cycle of the simulated actuator bank (all 32 actuators), as a ratio to its 100 us budget.

Not a test. The simulated boards step the bank once per millisecond beside the physics, so a step must stay
well under 100 us. Prints the derived parameters per actuator type, then the step cost (median, mean, p99)
of the bank tracking a 0.5 Hz sine in POSITION_FF mode under a constant load.

    .venv/bin/python bench/sim_actuators.py [--steps 3000]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.sim.actuator_model import NOMINAL_DT, ActuatorParams, default_params, parameter_table
from rh5_bringup.sim.actuators import ActuatorBank

BUDGET_US = 100.0


def step_times_us(params: ActuatorParams, steps: int, warmup: int) -> np.ndarray:
    """Wall time of each of ``steps`` bank steps [us], after ``warmup`` untimed ones."""
    bank = ActuatorBank(params)
    p = bank.params
    mid, amplitude = 0.5 * (p.position_min + p.position_max), 0.1 * p.stroke
    load, compensation = 0.1 * p.force_max, -0.1 * p.force_max
    bank.reset(mid)
    mode = np.full(p.num, CommandMode.POSITION_FF, dtype=np.int8)
    omega = math.pi
    times = np.empty(steps)
    for k in range(warmup + steps):
        t = k * NOMINAL_DT
        s, c = math.sin(omega * t), math.cos(omega * t)
        setpoint, v_ff = mid + amplitude * s, amplitude * omega * c
        start = time.perf_counter_ns()
        bank.step(NOMINAL_DT, mode, setpoint, velocity_ff=v_ff, force_ff=compensation, external_force=load)
        if k >= warmup:
            times[k - warmup] = time.perf_counter_ns() - start
    return times * 1e-3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="cycles to time")
    args = parser.parse_args()
    params = default_params()
    keys = ("N", "k_t", "K", "R", "I_max", "M", "b", "F_c", "kp_pos", "kp_vel", "ki_vel", "knee_speed")
    print(f"{'type':<11}{'n':>3} {'v_max':>9} {'f_max':>8} " + " ".join(f"{k:>10}" for k in keys))
    for row in parameter_table(params):
        values = " ".join(f"{row[k]:10.4g}" for k in keys)
        print(f"{row['type']:<11}{row['count']:>3} {row['velocity_max']:9.4g} {row['force_max']:8.4g} {values}")
    times = step_times_us(params, args.steps, warmup=300)
    median, p99 = float(np.median(times)), float(np.percentile(times, 99))
    print(
        f"step cost, {params.num} actuators, {params.substeps} sub-steps, {args.steps} cycles: "
        f"median {median:.1f} us ({median / BUDGET_US:.2f} of the {BUDGET_US:.0f} us budget), "
        f"mean {times.mean():.1f} us, p99 {p99:.1f} us ({p99 / BUDGET_US:.2f})"
    )


if __name__ == "__main__":
    main()
