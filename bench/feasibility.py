"""Feasibility bench: the paper's table of hardware limits for its six design-analysis motions, planned with the
paper's cost set and with the actuator limits in the problem, and the design-improvement heuristic on the 10 cm
vertical jump in actuator space.

Run: ``.venv/bin/python bench/feasibility.py [--motions a,b] [--max-iterations 200] [--no-design]
[--design-motion vertical_jump_10cm] [--design-space actuator|joint] [--scale knee:velocity ...]
[--factors 1,1.5,2,3,4,5,6] [--output FILE]``.

Solves every motion twice (Box-FDDP, progress on stderr): with the paper's cost set (``actuator_limits: false``;
the fast walk with the paper's own parameters, rh5_planner.motions.PAPER_SETTINGS: the paper's table reproduced)
and with the actuator limits (Table I stroke, velocity, force through the parallel
mechanisms; issue 14). Prints both feasibility tables (Markdown, our actuator-space columns beside the paper's
three), compares the paper's columns cell by cell (rh5_planner.feasibility.PAPER_FEASIBILITY), then runs the
heuristic (default: in actuator space, i.e. planned with the actuator limits and required to hold them; scaling
the limits the nominal solution violates) and prints its steps and the result both as the paper's joint-space
factor and as an actuator specification (``Knee actuator ... 140 -> 420 mm/s``). ``--design-space joint`` runs the
paper's joint-space heuristic instead. ``--output`` also writes everything to a Markdown file; ``--motions ""`` runs
the heuristic only. Slow: the jumps have 90-270 knots.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)

from rh5_planner.design import improve_design, jump_height_task, parse_limit
from rh5_planner.feasibility import FeasibilityTable
from rh5_planner.limit_analysis import LimitAnalysis, analyse
from rh5_planner.limit_scale import ACTUATOR_KINDS, JOINT_KINDS
from rh5_planner.motions import MOTIONS, PAPER_SETTINGS, get_motion
from rh5_planner.ocp import SolverSettings, solve
from rh5_planner.plan_cli import PAPER_MOTIONS, ProgressBar


def main() -> None:
    """Solve, tabulate, compare, then run the heuristic."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--motions", default=",".join(PAPER_MOTIONS))
    parser.add_argument("--max-iterations", type=int, default=200)
    parser.add_argument("--stop-threshold", type=float, default=1e-7)
    parser.add_argument("--nthreads", type=int, default=2)
    parser.add_argument("--no-design", action="store_true")
    parser.add_argument("--design-motion", default="vertical_jump_10cm")
    parser.add_argument("--scale", action="append", default=[], help="PATTERN:KIND (default: the violated limits)")
    parser.add_argument("--factors", default="1,1.5,2,3,4,5,6")
    parser.add_argument("--design-space", choices=("actuator", "joint"), default="actuator")
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args()
    names = [n for n in args.motions.split(",") if n]  # empty: heuristic only
    for name in [*names, args.design_motion]:
        if name not in MOTIONS:
            parser.error(f"unknown motion {name!r}; known: {sorted(MOTIONS)}")

    def settings(label: str) -> tuple[SolverSettings, ProgressBar]:
        bar = ProgressBar(args.max_iterations, args.stop_threshold, label=f"{label} ", interval_s=5.0)
        return SolverSettings(args.max_iterations, args.stop_threshold, args.nthreads, callback=bar), bar

    report: list[str] = []
    for title, limited in (("paper's cost set", False), ("with the actuator limits (issue 14)", True)):
        analyses, timing = [], []
        for name in names:
            solver_settings, bar = settings(f"{name}{' +act' if limited else ''}")
            start = time.perf_counter()
            overrides = {"actuator_limits": True} if limited else PAPER_SETTINGS.get(name, {"actuator_limits": False})
            result = solve(get_motion(name, overrides), solver_settings)
            log = result.solver_log
            bar.finish("converged" if result.converged else "NOT converged")
            analyses.append(analyse(result))
            timing.append(
                f"- {name}: {log.knots} knots, {log.iterations} iterations, "
                f"{'converged' if result.converged else 'NOT converged'} (stop {log.stop_criterion:.1e}), "
                f"solve {log.solve_time_s:.1f} s, total {time.perf_counter() - start:.1f} s"
            )
        if analyses:
            part = _table_text(f"Feasibility of the paper's motions: {title}", analyses, timing)
            print("\n".join(part), flush=True)
            report += part

    if not args.no_design:
        limits = [parse_limit(s) for s in args.scale] or None
        factors = tuple(float(f) for f in args.factors.split(","))
        solver_settings, bar = settings(args.design_motion)

        def on_step(step: object) -> None:
            bar.finish(step.describe())  # type: ignore[attr-defined]
            bar.restart()

        actuator_space = args.design_space == "actuator"
        result = improve_design(
            get_motion(args.design_motion, {"actuator_limits": actuator_space}),
            limits,
            factors=factors,
            settings=solver_settings,
            required=(*JOINT_KINDS, *ACTUATOR_KINDS) if actuator_space else JOINT_KINDS,
            on_step=on_step,
            task=jump_height_task() if get_motion(args.design_motion).kind == "jump" else None,
        )
        space = (
            "actuator space (planned with and required to hold the actuator limits)"
            if actuator_space
            else ("joint space (the paper's)")
        )
        design_text = ["", f"## Design-improvement heuristic, {space}", "", "```", result.report(), "```", ""]
        print("\n".join(design_text), flush=True)
        report += design_text
    if args.output is not None:
        args.output.parent.mkdir(parents=True, exist_ok=True)
        args.output.write_text("\n".join(report), encoding="utf-8")
        print(f"written: {args.output}", file=sys.stderr)


def _table_text(title: str, analyses: list[LimitAnalysis], timing: list[str]) -> list[str]:
    """One feasibility table in Markdown with the comparison to the paper, solve times and violations."""
    table = FeasibilityTable(analyses)
    out = [f"# {title}", "", table.to_markdown(), "", table.comparison_text(), *timing, ""]
    for a in analyses:
        details = "; ".join(f"{k}: {', '.join(v)}" for k, v in a.violations().items()) or "none"
        out.append(f"- {a.motion} violations: {details}")
    return [*out, ""]


if __name__ == "__main__":
    main()
