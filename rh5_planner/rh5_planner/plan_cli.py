"""``rh5-plan``: plan a motion offline, check it against every limit, write the trajectory file, plots and limit table.

Usage::

    rh5-plan MOTION [--set key=value ...] [--output-dir DIR] [--max-iterations N] [--no-plots]
    rh5-plan --list
    rh5-plan --table [MOTION ...]            # the paper's feasibility table, compared with ours
    rh5-plan --design MOTION [--scale knee:velocity ...] [--factors 1,1.5,2,3,4]
    rh5-plan --sweep MOTION key=start:stop:count ... [--address ADDR] [--workers N] [--output-dir DIR]

A progress bar on stderr shows iteration, cost, stop criterion and elapsed time while Box-FDDP runs. Values of
``--set`` are YAML (``--set length_m=0.4``, ``--set costs=[foot,com,joint]``). Exit codes: 0 done (and
converged), 1 the solver did not converge (files are still written), 2 bad input (unknown motion, parameter or
limit; for --sweep see rh5_planner.sweep.cli). No ROS needed. Crocoddyl is imported only when something is planned.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Final

import yaml

from rh5_msgs_py.progress import LiveLine

from .motions import MOTIONS, VERIFIED_MOTIONS, MotionError, MotionSpec, get_motion

if TYPE_CHECKING:
    from .limit_analysis import LimitAnalysis
    from .ocp import PlanResult, SolverSettings
    from .solver_log import ActuatorLimitLog

__all__ = ["ProgressBar", "main", "parse_overrides"]

PAPER_MOTIONS: Final = (
    "walk_with_5kg_weights",
    "fast_walk_1m_s",
    "squat_with_5kg_weights",
    "vertical_jump_1cm",
    "vertical_jump_10cm",
    "obstacle_jumps",
)
"""The six motions of the paper's design analysis (its tables tab:motionCharacteristics and tab:systemLimits)."""
DEFAULT_OUTPUT_DIR: Final = Path("out/plans")
EXIT_NOT_CONVERGED: Final = 1
EXIT_USAGE: Final = 2
DEFAULT_THREADS: Final = 2
"""Threads of the derivative pass for one plan (a sweep runs one thread per point, one point per core)."""


class UsageError(Exception):
    """Bad command-line input: reported with exit code 2."""


class ProgressBar:
    """Box-FDDP progress on a stream: ``[#####.....] it 12/200  cost 1.368e+03  stop 3.7e-05  4.1 s``.

    The bar fills with the stop criterion's way (log scale) from its first value to the threshold, or with the
    iteration count, whichever is further. On a terminal it redraws one line; otherwise it writes a line at
    most every ``interval_s`` (and always the last one), so logs stay short.
    """

    def __init__(
        self,
        max_iterations: int,
        stop_threshold: float,
        *,
        label: str = "",
        stream: IO[str] | None = None,
        width: int = 24,
        interval_s: float = 1.0,
    ) -> None:
        self.max_iterations = max(1, max_iterations)
        self.stop_threshold = stop_threshold
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.width = width
        self.interval_s = interval_s
        self.start = time.perf_counter()
        self._first_stop: float | None = None
        self._line = LiveLine(self.stream, interval_s)

    def fraction(self, iteration: int, stop: float) -> float:
        """How far the solve is, 0..1."""
        by_iteration = iteration / self.max_iterations
        by_stop = 0.0
        first = self._first_stop
        if first is not None and first > self.stop_threshold > 0 and stop > 0 and math.isfinite(stop):
            by_stop = math.log(first / stop) / math.log(first / self.stop_threshold)
        return min(1.0, max(0.0, by_iteration, by_stop))

    def __call__(self, iteration: int, cost: float, stop: float) -> None:
        """The solver callback: (iteration, cost, stop) after every Box-FDDP iteration."""
        if self._first_stop is None and math.isfinite(stop) and stop > 0:
            self._first_stop = stop
        filled = round(self.width * self.fraction(iteration, stop))
        elapsed = time.perf_counter() - self.start
        self._line.show(
            f"{self.label}[{'#' * filled}{'.' * (self.width - filled)}] it {iteration}/{self.max_iterations}  "
            f"cost {cost:.4g}  stop {stop:.2e}  {elapsed:.1f} s"
        )

    def restart(self) -> None:
        """Start over for the next solve (elapsed time, stop-criterion scale, last line)."""
        self.start = time.perf_counter()
        self._first_stop = None
        self._line = LiveLine(self.stream, self.interval_s)

    def finish(self, message: str) -> None:
        """End the bar with the final line and ``message`` (complete in one line even where a log has its numbers)."""
        self._line.finish(f"{self._line.last}  {message}" if self._line.last else f"{self.label}{message}")


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``["length_m=0.4", "costs=[foot,com]"]`` -> ``{"length_m": 0.4, "costs": ["foot", "com"]}`` (YAML values)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            msg = f"--set {item!r}: expected key=value"
            raise UsageError(msg)
        try:
            out[key.strip()] = yaml.safe_load(raw)
        except yaml.YAMLError as err:
            msg = f"--set {item!r}: value is not valid YAML ({err})"
            raise UsageError(msg) from None
    return out


def _motion(name: str, overrides: dict[str, Any]) -> MotionSpec:
    try:
        return get_motion(name, overrides)
    except MotionError as err:
        raise UsageError(str(err)) from None


def _settings(args: argparse.Namespace, callback: Any) -> SolverSettings:
    from .ocp import SolverSettings  # noqa: PLC0415  (Crocoddyl only when planning)

    return SolverSettings(
        max_iterations=args.max_iterations,
        stop_threshold=args.stop_threshold,
        nthreads=args.threads or DEFAULT_THREADS,
        callback=callback,
    )


def _solve(motion: MotionSpec, args: argparse.Namespace, stream: IO[str]) -> PlanResult:
    from .ocp import solve  # noqa: PLC0415

    bar = ProgressBar(args.max_iterations, args.stop_threshold, label=f"{motion.name} ", stream=stream)
    stream.write(f"{motion.name}: building and solving ({motion.n_knots} knot intervals)...\n")
    result = solve(motion, _settings(args, bar))
    log = result.solver_log
    bar.finish("converged" if result.converged else f"NOT converged (stop {log.stop_criterion:.2e})")
    return result


def _summary(result: PlanResult, analysis: LimitAnalysis, files: Sequence[Path]) -> str:
    from .feasibility import FeasibilityTable  # noqa: PLC0415

    log = result.solver_log
    lines = [
        f"motion: {result.motion.name} ({result.motion.kind}), {len(result.times)} knots, "
        f"{result.times[-1]:.2f} s, mass {log.mass_kg:.1f} kg",
        f"solver: {'converged' if result.converged else 'NOT converged'} after {log.iterations} iterations, "
        f"cost {log.cost:.6g}, stop {log.stop_criterion:.2e}, solve {log.solve_time_s:.2f} s",
        "",
        _actuator_line(log.actuator_limits),
        "",
        FeasibilityTable([analysis]).to_text().rstrip(),
        "",
    ]
    for kind, names in analysis.violations().items():
        lines.append(f"over the {kind} limit: {', '.join(names)}")
    worst = {kind: usage.worst(1)[0] for kind, usage in {**analysis.joint, **(analysis.actuator or {})}.items()}
    lines.append("peak utilisation: " + ", ".join(f"{k} {n} {100 * u:.0f} %" for k, (n, u) in worst.items()))
    c = analysis.contact
    lines.append(
        f"contacts: CoP inside {100 * c.cop_inside_ratio:.1f} %, friction cone {100 * c.friction_inside_ratio:.1f} % "
        f"of {c.contact_knots} foot-knots"
    )
    lines += ["", "written:", *(f"  {p}" for p in files)]
    return "\n".join(lines)


def _actuator_line(entry: ActuatorLimitLog) -> str:
    """The solver log's actuator limits in one line: what was enforced and the peak use at the knots and 1 kHz."""
    if not entry.enforced:
        return "actuator limits: not in the problem (the paper's cost set; --set actuator_limits=true adds them)"
    peaks = ", ".join(
        f"{kind} {p['1khz'][0]} {100 * max(p['knots'][1], p['1khz'][1]):.0f} %"
        for kind, p in (entry.peak_utilisation or {}).items()
    )
    verdict = "within" if entry.within_limits else f"{entry.violations_left} samples over"
    kinds = ", ".join(entry.enforced)
    return f"actuator limits: {kinds} enforced, {verdict} Table I at knots and 1 kHz (peaks: {peaks})"


def _plan(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .cost_config import load_cost_config  # noqa: PLC0415
    from .limit_analysis import analyse  # noqa: PLC0415

    motion = _motion(args.motion, parse_overrides(args.set))
    output_dir = Path(args.output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    result = _solve(motion, args, err)
    data = result.to_trajectory_data()
    analysis = analyse(data)
    files = [result.save(output_dir / f"{motion.name}.rh5traj")]
    table = output_dir / f"{motion.name}_limits.md"
    table.write_text(analysis.to_markdown(), encoding="utf-8")
    files.append(table)
    if not args.no_plots:
        from .plots import plot_actuators, plot_cop, plot_joints  # noqa: PLC0415

        fraction = float(load_cost_config()["contact_stability"]["cop_fraction"])
        files.append(plot_cop(data, output_dir / f"{motion.name}_cop.png", cop_fraction=fraction))
        files.append(plot_joints(data, output_dir / f"{motion.name}_joints.png"))
        files.append(plot_actuators(data, output_dir / f"{motion.name}_actuators.png"))
    out.write(_summary(result, analysis, files) + "\n")
    return 0 if result.converged else EXIT_NOT_CONVERGED


def _list(out: IO[str]) -> int:
    for name, motion in MOTIONS.items():
        status = "verified" if name in VERIFIED_MOTIONS else "unverified"
        paper = " (paper table)" if name in PAPER_MOTIONS else ""
        out.write(f"{name}: {motion.kind}, {motion.n_knots} knots, {status}{paper}\n")
        for key, value in motion.parameters().items():
            if key != "name":
                out.write(f"    {key} = {value}\n")
    return 0


def _table(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .feasibility import FeasibilityTable  # noqa: PLC0415
    from .limit_analysis import analyse  # noqa: PLC0415

    names = args.table or list(PAPER_MOTIONS)
    overrides = parse_overrides(args.set)
    motions = [_motion(n, overrides) for n in names]  # validate every name before the first solve
    analyses = [analyse(_solve(m, args, err)) for m in motions]
    table = FeasibilityTable(analyses)
    text = table.to_markdown() + "\n" + table.comparison_text()
    out.write(text)
    if args.output_dir is not None:
        path = Path(args.output_dir)
        path.mkdir(parents=True, exist_ok=True)
        (path / "feasibility.md").write_text(text, encoding="utf-8")
        out.write(f"written: {path / 'feasibility.md'}\n")
    return 0 if all(a.converged for a in analyses) else EXIT_NOT_CONVERGED


def _factors(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        msg = f"--factors {text!r}: expected comma-separated numbers (e.g. 1,1.5,2,3,4)"
        raise UsageError(msg) from None
    if not values or any(not (math.isfinite(v) and v > 0) for v in values):
        msg = f"--factors {text!r}: factors must be positive numbers"
        raise UsageError(msg)
    return values


def _design(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .design import DesignStep, improve_design, jump_height_task, parse_limit  # noqa: PLC0415

    motion = _motion(args.design, parse_overrides(args.set))
    try:
        limits = [parse_limit(s) for s in args.scale] if args.scale else None
    except ValueError as error:
        raise UsageError(str(error)) from None
    factors = _factors(args.factors)
    bar = ProgressBar(args.max_iterations, args.stop_threshold, label=f"{motion.name} ", stream=err)

    def on_step(step: DesignStep) -> None:
        bar.finish(step.describe())
        bar.restart()

    from .limit_scale import ACTUATOR_KINDS, JOINT_KINDS  # noqa: PLC0415

    # planned with the actuator limits (--set actuator_limits=true): a feasible scaling must hold them too, and is
    # reported as an actuator specification beside the joint-space factor
    required = (*JOINT_KINDS, *ACTUATOR_KINDS) if motion.actuator_limits else JOINT_KINDS
    result = improve_design(
        motion,
        limits,
        factors=factors,
        settings=_settings(args, bar),
        required=required,
        on_step=on_step,
        task=jump_height_task() if motion.kind == "jump" else None,
    )
    out.write(result.report() + "\n")
    return 0 if result.feasible else EXIT_NOT_CONVERGED


def _sweep(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    if len(args.sweep) < 2:
        raise UsageError("--sweep MOTION key=start:stop:count ...: at least one axis")
    from .sweep.cli import run  # noqa: PLC0415  (Crocoddyl and, for the Ray engine, Ray only for a sweep)
    from .sweep.grid import GridError  # noqa: PLC0415

    try:
        return run(args, parse_overrides(args.set), out, err)
    except GridError as error:
        raise UsageError(str(error)) from None


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``rh5-plan``."""
    parser = argparse.ArgumentParser(
        prog="rh5-plan",
        description="Plan an RH5 motion with Box-FDDP, check every limit, write the trajectory file, plots and table.",
    )
    parser.add_argument("motion", nargs="?", help="motion to plan (see --list)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--list", action="store_true", help="list the motions and their parameters")
    mode.add_argument(
        "--table", nargs="*", metavar="MOTION", help="feasibility table of these motions (default: the paper's six)"
    )
    mode.add_argument("--design", metavar="MOTION", help="run the design-improvement heuristic on MOTION")
    mode.add_argument(
        "--sweep",
        nargs="+",
        metavar="MOTION_OR_AXIS",
        help="sweep MOTION over a grid: key=start:stop:count or key=v1,v2 per axis; keys: motion parameters, "
        "speed_m_s (walks), design limits PATTERN:KIND (knee:velocity); Ray runs the points",
    )
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="motion parameter override")
    parser.add_argument(
        "--output-dir", default=None, help=f"output folder (default for planning: {DEFAULT_OUTPUT_DIR})"
    )
    parser.add_argument("--max-iterations", type=int, default=200, help="Box-FDDP iteration cap (default 200)")
    parser.add_argument("--stop-threshold", type=float, default=1e-7, help="Box-FDDP stop threshold (default 1e-7)")
    parser.add_argument(
        "--threads", type=int, default=None, help="threads of the derivative pass (default 2; 1 per point in a sweep)"
    )
    parser.add_argument("--no-plots", action="store_true", help="do not write the PNG plots")
    parser.add_argument(
        "--scale",
        action="append",
        default=[],
        metavar="PATTERN:KIND",
        help="limit to scale with --design, e.g. "
        "knee:velocity (KIND: position, velocity, torque; default: the limits the nominal solution violates)",
    )
    parser.add_argument("--factors", default="1,1.5,2,3,4", help="scale factors for --design (default 1,1.5,2,3,4)")
    _add_sweep_arguments(parser)
    return parser


def _add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """The sweep's own options (rh5_planner.sweep.cli; imported only for a sweep: it brings Crocoddyl)."""
    group = parser.add_argument_group("sweep (--sweep MOTION key=start:stop:count ...)")
    group.add_argument(
        "--engine",
        choices=("ray", "serial"),
        default="ray",
        help="ray (default): Ray tasks on a local instance or --address; serial: one point after the other here",
    )
    group.add_argument("--address", default=None, help="Ray cluster to run on (e.g. 127.0.0.1:6379 or auto)")
    group.add_argument("--workers", type=int, default=None, help="CPUs of the local Ray instance (default: cores)")
    group.add_argument("--no-warm-start", action="store_true", help="start every point cold")
    group.add_argument("--warm-chain", type=int, default=4, help="longest warm-start chain on the last axis (4)")
    group.add_argument("--restart", action="store_true", help="discard another sweep's checkpoint in the folder")
    group.add_argument("--no-figures", action="store_true", help="write the table only")


def main(argv: Sequence[str] | None = None, *, out: IO[str] | None = None, err: IO[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 1 not converged / infeasible, 2 bad input)."""
    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.max_iterations < 1:
            raise UsageError(f"--max-iterations must be >= 1, got {args.max_iterations}")
        if not (args.stop_threshold > 0):
            raise UsageError(f"--stop-threshold must be > 0, got {args.stop_threshold}")
        if args.output_dir is not None and Path(args.output_dir).exists() and not Path(args.output_dir).is_dir():
            raise UsageError(f"--output-dir {args.output_dir}: not a folder")
        if args.list:
            return _list(out)
        if args.table is not None:
            if args.motion:
                raise UsageError("give the motions after --table, not before")
            return _table(args, out, err)
        if args.design:
            if args.motion:
                raise UsageError("give the motion after --design only")
            return _design(args, out, err)
        if args.sweep:
            if args.motion:
                raise UsageError("give the motion after --sweep only: --sweep MOTION key=start:stop:count ...")
            return _sweep(args, out, err)
        if not args.motion:
            raise UsageError("a MOTION (or --list, --table, --design) is required")
        if args.scale:
            raise UsageError("--scale only applies with --design")
        if args.output_dir is None:
            args.output_dir = str(DEFAULT_OUTPUT_DIR)
        return _plan(args, out, err)
    except UsageError as error:
        parser.print_usage(err)
        err.write(f"rh5-plan: error: {error}\n")
        return EXIT_USAGE


def entry_point() -> None:
    """Console script ``rh5-plan``."""
    sys.exit(main())


if __name__ == "__main__":
    entry_point()
