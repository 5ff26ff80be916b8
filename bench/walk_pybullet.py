"""The paper's PyBullet check of the planned 5 kg walk, and how robust its outcome is.

Plans walk_with_5kg_weights (or loads ``--trajectory``), then plays it in this process on the physics
(rh5_bringup.sim.replay): the paper's setup (rigid-body robot, PyBullet's joint position motors), the same PD
idea on the suite's physics with the actuators' reflected inertia, and the suite's board chain; each for several
ground friction coefficients around the planner's mu. Prints the floating-base deviation during the walk
against the paper's band (x, y +-10 mm, z +5 mm), the largest stance-sole tilt, and how close the plan runs to
its contact constraints (CoP region edge, friction cone); plots the deviations at the first friction.
Deterministic: no ROS, no wall-clock timing.

    .venv/bin/python bench/walk_pybullet.py [--trajectory FILE] [--friction 0.7,0.8] [--feedforward] [--plot PNG]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from rh5_bringup.analysis.figures import replay_figure
from rh5_bringup.analysis.metrics import BASE_BAND_M
from rh5_bringup.sim.replay import CONTROLLERS, replay
from rh5_msgs_py.trajectory_file import TrajectoryData, load_trajectory
from rh5_planner.feet import FOOT_SIZE_M


def plan_walk() -> TrajectoryData:
    """Plan the 5 kg walk with the default settings (as `rh5 experiment` does)."""
    from rh5_planner.motions import get_motion  # noqa: PLC0415 - only when no trajectory file is given
    from rh5_planner.ocp import solve  # noqa: PLC0415

    started = time.perf_counter()
    result = solve(get_motion("walk_with_5kg_weights"))
    log = result.solver_log
    print(
        f"planned walk_with_5kg_weights: {log.iterations} iterations, converged {log.converged}, "
        f"{time.perf_counter() - started:.1f} s"
    )
    return result.to_trajectory_data()


def constraint_margins(data: TrajectoryData) -> str:
    """How much of the plan's contact time sits at the CoP region's edge, and the largest friction use."""
    from rh5_planner.cost_config import load_cost_config  # noqa: PLC0415 - the planner's cone settings

    cone = load_cost_config()["contact_stability"]
    mu, region = float(cone["mu"]), float(cone["cop_fraction"])
    cop = data.cop[data.contact_phases]  # (contacts, 2)
    half = 0.5 * region * np.array(FOOT_SIZE_M)
    at_edge = (np.abs(cop) >= 0.9 * half).any(axis=1)
    wrench = data.contact_wrenches[data.contact_phases]
    loaded = wrench[:, 2] > 1.0
    ratio = np.hypot(wrench[loaded, 0], wrench[loaded, 1]) / wrench[loaded, 2]
    return (
        f"plan: CoP within 10 % of the {region:.0%} region's edge at {at_edge.mean():.0%} of {len(cop)} "
        f"foot-knots in contact; largest tangential/normal force {ratio.max():.2f} (mu {mu})"
    )


def _band(dev_mm: np.ndarray) -> str:
    inside = all(
        lo >= 1e3 * BASE_BAND_M[ax][0] and hi <= 1e3 * BASE_BAND_M[ax][1]
        for ax, (lo, hi) in zip("xyz", dev_mm, strict=True)
    )
    return "inside" if inside else "outside"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trajectory", help="trajectory file to play (default: plan the walk now)")
    parser.add_argument("--friction", default="0.6,0.65,0.7,0.75,0.8,1.0", help="ground friction coefficients")
    parser.add_argument("--feedforward", action="store_true", help="feed the planned torques forward too")
    parser.add_argument("--plot", default="out/bench/walk_pybullet.png", help="figure of the deviations")
    args = parser.parse_args(argv)
    data = load_trajectory(args.trajectory) if args.trajectory else plan_walk()
    print(constraint_margins(data))
    frictions = [float(f) for f in args.friction.split(",")]
    walk_end = float(data.motion.get("parameters", {}).get("total_time_s", data.times[-1] - data.times[0]))
    print(
        f"while walking (the first {walk_end:g} s of {data.times[-1] - data.times[0]:g} s planned); last column: "
        "the largest |x|, |y| including the rest after the walk [mm]"
    )
    print(
        f"{'controller':10s} {'mu':>5s}  {'x [mm]':>15s} {'y [mm]':>15s} {'z [mm]':>15s}  {'sole tilt':>9s}  "
        "paper band  with rest"
    )
    worst: dict[str, float] = {}
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for controller in CONTROLLERS:
        for mu in frictions:
            result = replay(data, controller, friction_coefficient=mu, torque_feedforward=args.feedforward)
            if mu == frictions[0]:
                curves[controller] = (result.times, result.base_deviation)
            walking = result.base_deviation[result.times <= walk_end + 1e-9] * 1e3
            dev = np.stack([walking.min(axis=0), walking.max(axis=0)], axis=1)
            cells = " ".join(f"[{lo:+6.1f},{hi:+6.1f}]" for lo, hi in dev)
            rest = float(np.abs(result.base_deviation[:, :2]).max() * 1e3)
            tilt = np.degrees(result.max_sole_tilt)
            print(f"{controller:10s} {mu:5.2f}  {cells}  {tilt:7.2f} deg  {_band(dev):10s}  {rest:8.1f}")
            worst[controller] = max(worst.get(controller, 0.0), float(np.abs(dev[:2]).max()))
    for controller, value in worst.items():
        print(f"{controller}: largest |x|, |y| while walking, over the frictions: {value:.1f} mm (paper: 10 mm)")
    plot = Path(args.plot)
    plot.parent.mkdir(parents=True, exist_ok=True)
    title = f"walk_with_5kg_weights in PyBullet, mu {frictions[0]}: measured minus planned base position"
    print(f"figure: {replay_figure(curves, plot, title)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
