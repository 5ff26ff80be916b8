"""Cost of the physics-mode simulation (boards + mapper + PyBullet): median and p99.

Runs the coupled simulation of rh5_bringup.sim.physics in this process, the robot standing on its boards
(crane released). A 1 ms board cycle is two 0.5 ms sub-steps (boards' cascade, tau = J^T f, PyBullet step,
joint read); the bench times each part of every sub-step, then whole 1 ms cycles as the node runs them.
Usage: ``python bench/physics.py [--cycles N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.sim.physics import build_physics
from rh5_msgs_py.names import NUM_ACTUATORS


def main() -> None:
    """Time ``--cycles`` cycles after a settling second; print median and p99 per part in microseconds."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=3000)
    args = parser.parse_args()
    coupled = build_physics()
    world = coupled.world
    mode = np.full(NUM_ACTUATORS, int(CommandMode.POSITION))
    target = coupled.position.copy()
    for k in range(1000):
        if k == 200:
            world.release_support()
        coupled.step(1e-3, mode, target)
    parts = {name: np.empty(args.cycles) for name in ("boards", "mapper", "pybullet", "total")}
    clock = time.perf_counter_ns
    for k in range(args.cycles):
        t0 = clock()
        measured = coupled._board_cycle(world.time_step, mode, target, None, None, None)
        t1 = clock()
        tau = coupled.torques(measured.force)
        t2 = clock()
        world.step(tau, (coupled.q, coupled.v))
        t3 = clock()
        coupled._read()  # the joint read and map: the other half of the mapper share
        t4 = clock()
        q_read = world.joint_state()  # the PyBullet part of the read, for the split
        t5 = clock()
        del q_read
        parts["boards"][k] = t1 - t0
        parts["pybullet"][k] = t3 - t2 + (t5 - t4)
        parts["mapper"][k] = t2 - t1 + (t4 - t3) - (t5 - t4)
        parts["total"][k] = t4 - t0
    print(f"physics sub-step ({world.time_step * 1e3:.1f} ms) over {args.cycles} sub-steps (us):")
    for name, values in parts.items():
        us = values / 1e3
        print(f"  {name:<9} median {np.median(us):7.1f}  p99 {np.percentile(us, 99):7.1f}")
    cycles = np.empty(args.cycles)
    for k in range(args.cycles):
        t0 = clock()
        coupled.step(1e-3, mode, target)
        cycles[k] = clock() - t0
    us = cycles / 1e3
    print(f"whole 1 ms board cycle: median {np.median(us):.1f} us, p99 {np.percentile(us, 99):.1f} us (CPU per ms)")
    print(f"  base drift {np.linalg.norm(world.base_pose().position[:2]) * 1e3:.2f} mm, mass {world.total_mass:.1f} kg")
    world.close()


if __name__ == "__main__":
    main()
