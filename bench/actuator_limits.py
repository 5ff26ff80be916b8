"""Actuator-limits bench (issue 14): each motion planned with the paper's cost set and with the actuator limits.

Run: ``.venv/bin/python bench/actuator_limits.py [--motions a,b] [--plots out/bench]``
(default: the six motions planned with actuator limits by default, and the fast walk).

Per motion and plan: convergence, iterations, solve time, the peak use (1 = the Table I limit) of the linear
actuators' stroke, velocity and force at the knots and along the 1 kHz interpolation (worst actuator named), the
joint-space violations, and the CoP / friction-cone share of the contact knots with the smallest normal force.
Writes ``actuators_<motion>.png`` per motion: the plan with the actuator limits in colour, without them (the
paper's cost set, for the fast walk with our parameters) in grey.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)

from rh5_planner.actuator_constraints import LINEAR_ACTUATORS, check_trajectory
from rh5_planner.limit_analysis import analyse
from rh5_planner.motions import MOTIONS, get_motion
from rh5_planner.ocp import PlanResult, SolverSettings, solve
from rh5_planner.plots import plot_actuators

DEFAULT = [n for n, m in MOTIONS.items() if m.actuator_limits]


def _row(label: str, plan: PlanResult) -> str:
    log = plan.solver_log
    data = plan.to_trajectory_data()
    check = check_trajectory(data)
    peaks = []
    for kind in ("stroke", "velocity", "force"):
        knots, fine = check.knots[kind], check.samples[kind]
        worst = int(fine.argmax())
        peaks.append(f"{kind} {knots.max():.2f}/{fine.max():.2f} ({LINEAR_ACTUATORS[worst]})")
    analysis = analyse(data)
    joint = {k: v for k, v in analysis.violations().items() if k in ("position", "velocity", "torque")}
    contact = analysis.contact
    fz = plan.wrenches[plan.contact_phases][:, 2].min()
    return (
        f"  {label:13s} {'converged' if plan.converged else 'NOT converged'} {log.iterations:4d} it "
        f"{log.solve_time_s:6.1f} s | knots/1 kHz: {', '.join(peaks)} | joints over: {joint or 'none'} | "
        f"CoP in {100 * contact.cop_inside_ratio:.1f} %, friction {100 * contact.friction_inside_ratio:.1f} %, "
        f"min f_z {fz:.0f} N"
    )


def main() -> None:
    """Plan each motion both ways, print the comparison, write the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motions", default=",".join(DEFAULT))
    parser.add_argument("--plots", type=Path, default=Path("out/bench"))
    parser.add_argument("--max-iterations", type=int, default=300)
    args = parser.parse_args()
    settings = SolverSettings(max_iterations=args.max_iterations)
    for name in [n for n in args.motions.split(",") if n]:
        motion = get_motion(name)
        paper = solve(motion.with_overrides({"actuator_limits": False}), settings)
        ours = solve(motion.with_overrides({"actuator_limits": True}), settings)
        print(f"{name}:", flush=True)
        print(_row("actuators off", paper), flush=True)
        print(_row("actuators on", ours), flush=True)
        figure = plot_actuators(
            ours.to_trajectory_data(), args.plots / f"actuators_{name}.png", reference=paper.to_trajectory_data()
        )
        print(f"  figure: {figure}", flush=True)


if __name__ == "__main__":
    main()
