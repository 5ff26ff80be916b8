"""Planner benchmark: solve time, iterations and ms per knot-iteration of every motion, against Talos walking.

Run: ``.venv/bin/python bench/planner.py [--motions a,b] [--repeat N] [--walk-repeat 5] [--nthreads 2]
[--contact-form wrench_cone|friction_and_cop] [--no-matched]`` (default: all nine motions once, the walk five
times, the contact-stability form of costs.yaml).

The reference is Crocoddyl's own full-Talos walking problem from example-robot-data, built with
``crocoddyl.utils.biped`` here in the bench only (that module is not API; the planner does not use it), with
the parameters of design/crocoddyl_wheels.md (0.6 m, 0.1 m, dt 0.03, 25 step knots, 2 support knots). Our
motions print ms per knot-iteration as a ratio to Talos's (target <= 1.0) and the median solve time of
walk_with_5kg_weights (target <= 2 s). Times are wall-clock of ``solve()`` only; the 2-vCPU machine is noisy,
so minima and medians are both printed. The last column counts joints whose solution leaves the position /
velocity limits (the design-analysis motions of the paper's feasibility table do; torques never leave the box).

Crocoddyl's cost per knot-iteration grows with the horizon on this machine: the same Talos walk costs ~0.38 ms at
27 knots, ~0.43 ms at 55 and ~0.58-0.63 ms at 270 (its derivative pass per knot is ~45 % dearer at 110 knots than
at 55, likely the knot data outgrowing the caches). So the ``@T`` columns also solve the Talos walk discretised into
as many knots as the motion (same 0.6 m gait, dt scaled; median of three solves) and print the ratio to that.

Motions planned with the actuator limits (issue 14) are also solved without them, interleaved, and a second table
prints ms per knot-iteration on / off (target <= 1.3) and the peak actuator utilisation (stroke/velocity/force, knots
and 1 kHz) of both plans; ``--no-on-off`` skips those solves.
"""

from __future__ import annotations

import argparse
import functools
import statistics
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import crocoddyl  # before pinocchio (design/crocoddyl_wheels.md)
import numpy as np

from rh5_planner.actuator_bounds import ACTUATOR_LIMIT_KINDS
from rh5_planner.actuator_constraints import check_trajectory
from rh5_planner.cost_config import load_cost_config
from rh5_planner.motions import MOTIONS, get_motion
from rh5_planner.ocp import CONTACT_STABILITY_FORMS, PlanResult, SolverSettings, solve

TALOS_KNOTS = 55
"""Knots of the reference walk (dt 0.03 s, 25 knots per step, 2 per double support)."""


@functools.cache
def _talos_model() -> Any:
    """Talos's Pinocchio model, parsed once for all the reference solves (the gait builder does not change it)."""
    import example_robot_data  # noqa: PLC0415

    return example_robot_data.load("talos").model


def talos_walk(nthreads: int, max_iterations: int, knots: int = TALOS_KNOTS) -> dict[str, float]:
    """Crocoddyl's full-Talos walking problem, solved like ours (BoxFDDP, quasi-static warm start); ``knots``
    other than 55 discretises the same walk finer or coarser (step and support knots scaled, dt scaled inversely)."""
    from crocoddyl.utils.biped import SimpleBipedGaitProblem  # noqa: PLC0415

    model = _talos_model()
    gait = SimpleBipedGaitProblem(model, "right_sole_link", "left_sole_link")
    q0 = model.referenceConfigurations["half_sitting"].copy()
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    scale = knots / TALOS_KNOTS
    problem = gait.createWalkingProblem(x0, 0.6, 0.1, 0.03 / scale, round(25 * scale), max(1, round(2 * scale)))
    problem.nthreads = nthreads
    solver = crocoddyl.SolverBoxFDDP(problem)
    solver.th_stop = 1e-7
    xs = [x0] * (problem.T + 1)
    us = problem.quasiStatic([x0] * problem.T)
    start = time.perf_counter()
    converged = solver.solve(xs, us, max_iterations, False)
    elapsed = time.perf_counter() - start
    # iterations run, counted as the planner counts them (one per callback): solve() returns from inside its loop
    # when it converges, with iter the 0-based index of that last iteration
    iterations = solver.iter + 1 if converged else solver.iter
    return {
        "solve_time_s": elapsed,
        "iterations": iterations,
        "knots": problem.T,
        "ms_per_knot_iteration": 1e3 * elapsed / (problem.T * max(1, iterations)),
        "converged": solver.stop <= 1e-7,
    }


def main() -> None:
    """Run the benchmark: Talos, then one row per motion, then the totals against the targets."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motions", default=",".join(MOTIONS))
    parser.add_argument("--repeat", type=int, default=1, help="solves per motion (median and min printed)")
    parser.add_argument("--walk-repeat", type=int, default=5, help="solves of walk_with_5kg_weights (median target)")
    parser.add_argument("--nthreads", type=int, default=2)
    parser.add_argument("--max-iterations", type=int, default=300)
    parser.add_argument("--stop-threshold", type=float, default=1e-7)
    parser.add_argument(
        "--contact-form", choices=CONTACT_STABILITY_FORMS, help="costs.yaml contact_stability.form (default: as there)"
    )
    parser.add_argument(
        "--no-matched", action="store_true", help="skip the Talos walks with each motion's knot count (@T columns)"
    )
    parser.add_argument(
        "--no-on-off", action="store_true", help="skip the solves with the actuator limits off (on/off ratio)"
    )
    parser.add_argument(
        "--plot", default="out/bench/planner.png", help="figure: ms per knot-iteration over knots, ours and Talos's"
    )
    args = parser.parse_args()
    names = [n for n in args.motions.split(",") if n]
    for name in names:
        if name not in MOTIONS:
            parser.error(f"unknown motion {name!r}; known: {sorted(MOTIONS)}")

    talos_runs = [talos_walk(args.nthreads, args.max_iterations) for _ in range(max(3, args.repeat))]
    talos_ms = statistics.median(r["ms_per_knot_iteration"] for r in talos_runs)
    print(
        f"talos_walk (reference): knots {talos_runs[0]['knots']}, iterations {talos_runs[0]['iterations']}, "
        f"solve min/median {min(r['solve_time_s'] for r in talos_runs):.3f}/"
        f"{statistics.median(r['solve_time_s'] for r in talos_runs):.3f} s, {talos_ms:.3f} ms per knot-iteration"
    )
    config = load_cost_config()
    if args.contact_form:
        config["contact_stability"]["form"] = args.contact_form
    print(f"contact stability: {config['contact_stability'].get('form', 'wrench_cone')}")
    settings = SolverSettings(
        max_iterations=args.max_iterations,
        stop_threshold=args.stop_threshold,
        nthreads=args.nthreads,
        cost_config=config,
    )
    columns = (
        ("knots", 5),
        ("iter", 5),
        ("conv", 5),
        ("stop", 12),
        ("min s", 7),
        ("med s", 7),
        ("ms/k-it", 8),
        ("ratio", 6),
        ("T-ref", 6),
        ("ms@T", 6),
        ("ratio@T", 7),
    )
    print(f"{'motion':26s} " + " ".join(f"{c:>{w}s}" for c, w in columns) + "  limits (joints over: position/velocity)")
    walk_median, total, ratios, matched_ratios = None, 0.0, [], []
    on_off: list[str] = []  # rows of the actuator-limits table
    on_off_ratios: list[float] = []
    ours: list[tuple[str, int, float]] = []  # (motion, knots, ms per knot-iteration) for the figure
    matched: dict[int, tuple[int, float]] = {}  # motion knots -> (reference knots, median ms/knot-iteration)
    for name in names:
        repeat = args.walk_repeat if name == "walk_with_5kg_weights" else args.repeat
        motion = get_motion(name)
        results, paper = [], []
        for _ in range(max(1, repeat)):  # with the actuator limits on, the same motion without them interleaved
            results.append(solve(motion, settings))
            if motion.actuator_limits and not args.no_on_off:
                paper.append(solve(motion.with_overrides({"actuator_limits": False}), settings))
        if paper:
            on_off_ratios.append(_on_off_row(name, results, paper, on_off))
        logs = [r.solver_log for r in results]
        times = [log.solve_time_s for log in logs]
        ms = statistics.median(log.ms_per_knot_iteration for log in logs)
        median = statistics.median(times)
        total += median
        ratios.append(ms / talos_ms)
        ours.append((name, logs[0].knots, ms))
        if name == "walk_with_5kg_weights":
            walk_median = median
        at_t = "     -      -       -"
        if not args.no_matched:
            knots = logs[0].knots
            if knots not in matched:
                runs = [talos_walk(args.nthreads, args.max_iterations, knots) for _ in range(max(3, args.repeat))]
                matched[knots] = (runs[0]["knots"], statistics.median(r["ms_per_knot_iteration"] for r in runs))
            ref_knots, ref_ms = matched[knots]
            matched_ratios.append(ms / ref_ms)
            at_t = f"{ref_knots:6d} {ref_ms:6.3f} {matched_ratios[-1]:7.2f}"
        print(
            f"{name:26s} {logs[0].knots:5d} {logs[0].iterations:5d} {logs[0].converged!s:>5s} "
            f"{logs[0].stop_reason:>12s} {min(times):7.3f} {median:7.3f} {ms:8.3f} {ms / talos_ms:6.2f} "
            f"{at_t}  {_violations(results[0])}"
        )
    print("ratio = our ms per knot-iteration / Talos's (target <= 1.0)")
    if matched_ratios:
        print("ratio@T = the same, against the Talos walk discretised into T-ref knots (about the motion's)")
    print(f"all {len(names)} motions: {total:.1f} s of median solve time (target <= 60 s); max ratio {max(ratios):.2f}")
    if matched_ratios:
        print(f"max ratio@T {max(matched_ratios):.2f}")
    if walk_median is not None:
        verdict = "meets" if walk_median <= 2.0 else "misses"
        print(f"walk_with_5kg_weights median solve time {walk_median:.3f} s ({verdict} the 2 s target)")
    if on_off:
        print()
        print("actuator limits (issue 14): the same motion with them on and off (paper's cost set), interleaved")
        print(
            f"{'motion':26s} {'it on':>5s} {'it off':>6s} {'ms/k-it on':>10s} {'off':>6s} {'ratio':>6s} "
            f"{'cpu on':>7s} {'cpu off':>7s} {'ratio':>6s} {'s on':>6s} {'s off':>6s}  "
            "peak actuator use on / off (stroke, velocity, force)"
        )
        print("\n".join(on_off))
        print(
            f"CPU ms per knot-iteration, actuator limits on / off: max {max(on_off_ratios):.2f}, "
            f"median {statistics.median(on_off_ratios):.2f} (target <= 1.3; wall-clock columns beside it)"
        )
    references = sorted({(talos_runs[0]["knots"], talos_ms), *matched.values()})
    print(f"figure: {_horizon_figure(Path(args.plot), references, ours)}")


def _horizon_figure(path: Path, talos: Sequence[tuple[int, float]], ours: Sequence[tuple[str, int, float]]) -> Path:
    """ms per knot-iteration over the number of knots: the Talos walk at each discretisation (a line) and our
    motions (labelled points), so a ratio's horizon part is seen at a glance."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415

    fig = Figure(figsize=(7.0, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    knots, ms = zip(*talos, strict=True)
    ax.plot(knots, ms, "o-", color="0.4", label="Crocoddyl's Talos walk, discretised into that many knots")
    for name, n, value in ours:
        ax.plot(n, value, "s", color="tab:blue")
        ax.annotate(name, (n, value), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.plot([], [], "s", color="tab:blue", label="our motions")
    ax.set_xlabel("knots")
    ax.set_ylabel("solve time per knot and iteration [ms]")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def _on_off_row(name: str, on: Sequence[PlanResult], off: Sequence[PlanResult], rows: list[str]) -> float:
    """Append the table row of one motion solved with the actuator limits on and off; return the ratio of the
    median ms per knot-iteration (on / off)."""
    ms_on = statistics.median(r.solver_log.ms_per_knot_iteration for r in on)
    ms_off = statistics.median(r.solver_log.ms_per_knot_iteration for r in off)
    cpu_on = statistics.median(r.solver_log.cpu_ms_per_knot_iteration for r in on)
    cpu_off = statistics.median(r.solver_log.cpu_ms_per_knot_iteration for r in off)
    s_on = statistics.median(r.solver_log.solve_time_s for r in on)
    s_off = statistics.median(r.solver_log.solve_time_s for r in off)

    def peaks(plan: PlanResult) -> str:
        check = check_trajectory(plan.to_trajectory_data())
        return "/".join(f"{max(check.knots[k].max(), check.samples[k].max()):.2f}" for k in ACTUATOR_LIMIT_KINDS)

    rows.append(
        f"{name:26s} {on[0].solver_log.iterations:5d} {off[0].solver_log.iterations:6d} {ms_on:10.3f} "
        f"{ms_off:6.3f} {ms_on / ms_off:6.2f} {cpu_on:7.3f} {cpu_off:7.3f} {cpu_on / cpu_off:6.2f} {s_on:6.2f} "
        f"{s_off:6.2f}  {peaks(on[0])} / {peaks(off[0])}"
    )
    return cpu_on / cpu_off


def _violations(plan: PlanResult) -> str:
    """Joints whose planned position / velocity leaves the limits (the solution, not the planner's barrier box)."""
    nq = plan.robot.model.nq
    q, v = plan.xs[:, 7:nq], plan.xs[:, nq + 6 :]
    over_q = int(np.count_nonzero(((q < plan.robot.q_lower - 1e-9) | (q > plan.robot.q_upper + 1e-9)).any(axis=0)))
    ratio = np.abs(v).max(axis=0) / plan.robot.v_max
    over_v = int(np.count_nonzero(ratio > 1 + 1e-9))
    return f"{over_q}/{over_v} (peak velocity {ratio.max():.2f} x limit)"


if __name__ == "__main__":
    main()
