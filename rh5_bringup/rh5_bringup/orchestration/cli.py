"""The ``rh5`` command line: start the suite (``rh5 up``), run experiments (``rh5 experiment``), write reports,
describe and recover bags (``rh5 bag``, bag_cli.py)."""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from rh5_bringup.orchestration.launcher import Bringup, SuiteRun, check_parameter_names, load_bringup
from rh5_bringup.orchestration.service_calls import call_lifecycle, call_set_bool, call_trigger  # noqa: F401 (set_bool: re-exported)
from rh5_bringup.orchestration.session import SuiteSession, run_dir
from rh5_bringup.recording.bag_cli import add_bag_parser, bag_command
from rh5_msgs_py.ros_env import chosen_domain_id

DEFAULT_LOG_ROOT = Path(".ros") / "log"


def format_report(run: SuiteRun, exit_codes: dict[str, int]) -> str:
    """One block per node: its exit code and what it saw and sent."""
    lines = []
    for proc in run.processes:
        summary = proc.summary() or {}
        seen = ", ".join(f"{t}={n}" for t, n in sorted(summary.get("seen", {}).items())) or "nothing"
        sent = ", ".join(f"{t}={n}" for t, n in sorted(summary.get("sent", {}).items())) or "nothing"
        extra = {k: v for k, v in summary.items() if k not in ("node", "seen", "sent")}
        lines.append(f"{proc.spec.name:<13} exit {exit_codes[proc.spec.name]}")
        lines.append(f"  saw:  {seen}")
        lines.append(f"  sent: {sent}")
        if extra:
            lines.append("  state: " + ", ".join(f"{k}={v}" for k, v in sorted(extra.items())))
        if not summary:
            lines.append(f"  (no summary; see {proc.stderr_path})")
    return "\n".join(lines)


def up(
    bringup: Bringup,
    duration_s: float | None,
    log_root: Path,
    start: bool = False,
    domain: tuple[int | None, str] = (None, "leased: free on this machine"),
) -> int:
    """Start the suite, wait until every node is in the graph, run, stop cleanly and report.

    ``domain``: the ROS_DOMAIN_ID to run in and where it came from (``chosen_domain_id``).
    """
    with SuiteSession(bringup, run_dir(log_root), domain_id=domain[0]) as session:
        run = session.run
        print(f"rh5 up: ROS_DOMAIN_ID={run.domain_id} ({domain[1]}), logs in {run.log_dir}", flush=True)
        missing = session.start()
        names = bringup.node_names()
        if missing:
            print(f"rh5 up: never appeared in the ROS graph: {sorted(missing)}", file=sys.stderr)
            print(run.why_missing(missing), file=sys.stderr)
        else:
            print(f"rh5 up: {len(names)} nodes running: {', '.join(sorted(names))}", flush=True)
            if start:
                print("rh5 up: planning the planner's motion ...", flush=True)
                _, message = call_trigger(session.node, session.service("planner", "plan"), timeout_s=120.0)
                print(f"rh5 up: planner plan: {message}", flush=True)
                _, message = call_lifecycle(session.node, session.service("driver", "change_state"), "activate")
                print(f"rh5 up: driver lifecycle: {message}", flush=True)
                _, message = call_trigger(session.node, session.service("stabilizer", "start"))
                print(f"rh5 up: stabilizer start: {message}", flush=True)
        deadline = None if duration_s is None else time.monotonic() + duration_s
        while (
            not session.stop_requested and not session.crashed() and (deadline is None or time.monotonic() < deadline)
        ):
            time.sleep(0.05)
        if session.crashed():
            print(f"rh5 up: stopped on their own: {session.crashed()}", file=sys.stderr)
        exit_codes = session.close()
    print(format_report(run, exit_codes), flush=True)
    return 0 if not missing and all(code == 0 for code in exit_codes.values()) else 1


def experiment(args: argparse.Namespace) -> int:
    """``rh5 experiment``: plan or reuse, run on the simulated robot, record, report."""
    from rh5_bringup.orchestration.experiment import ExperimentError, ExperimentSettings, run_experiment  # noqa: PLC0415
    from rh5_planner.motions import MotionError, get_motion  # noqa: PLC0415
    from rh5_planner.plan_cli import UsageError, parse_overrides  # noqa: PLC0415

    try:
        overrides = parse_overrides(args.set)
        get_motion(args.motion, overrides)
        node_parameters: dict[str, dict[str, Any]] = {}
        for dotted, value in parse_overrides(args.param).items():
            node, sep, key = dotted.partition(".")
            if not sep or not key:
                msg = f"--param {dotted}: expected NODE.KEY=VALUE"
                raise ValueError(msg)
            node_parameters.setdefault(node, {})[key] = value
        if args.out.exists() and not args.out.is_dir():
            msg = f"--out {args.out}: not a folder"
            raise ValueError(msg)
        try:
            check_parameter_names(load_bringup(args.bringup), node_parameters)
        except ValueError as err:
            msg = f"--param: {err}"
            raise ValueError(msg) from None
        domain_id, _ = chosen_domain_id(args.domain_id)
    except (ValueError, KeyError, MotionError, UsageError) as err:
        print(f"rh5 experiment: {err}", file=sys.stderr)
        return 2
    settings = ExperimentSettings(
        args.motion,
        overrides,
        sim=args.sim,
        output_root=args.out,
        replan=args.replan,
        hold_after_s=args.hold,
        bringup=args.bringup,
        report=not args.no_report,
        node_parameters=node_parameters,
        composed=not args.separate,
        domain_id=domain_id,
    )
    try:
        result = run_experiment(settings, progress=lambda text: print(f"rh5 experiment: {text}", flush=True))
    except ExperimentError as err:
        print(f"rh5 experiment: {err}", file=sys.stderr)
        return 1
    print(f"rh5 experiment: bag {result.bag}")
    if result.report is not None:
        print(f"rh5 experiment: report {result.report}")
    ok = result.outcome == "completed" and all(code == 0 for code in result.exit_codes.values())
    return 0 if ok else 1


def report(args: argparse.Namespace) -> int:
    """``rh5 report BAG``: (re)write the report of a recording (exit 2 for a path that is not a readable bag)."""
    from rh5_bringup.analysis.__main__ import main as report_main  # noqa: PLC0415

    argv = [str(args.bag), "--joints", args.joints]
    if args.out is not None:
        argv += ["--out", str(args.out)]
    return report_main(argv)


SEPARATE_HELP = (
    "run the driver, mapper and stabilizer as three processes linked by topics (development) instead of the "
    "control process's one real-time cycle"
)


DOMAIN_HELP = (
    "ROS_DOMAIN_ID of the run (default: ROS_DOMAIN_ID of the environment when set, else one free on this machine)"
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``rh5``."""
    parser = argparse.ArgumentParser(prog="rh5", description="RH5 control suite command line.")
    commands = parser.add_subparsers(dest="command", required=True)
    up_parser = commands.add_parser("up", help="start the suite; Ctrl-C stops every node cleanly")
    up_parser.add_argument("--sim", choices=["kinematic", "physics"], default="kinematic", help="simulated hardware")
    up_parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    up_parser.add_argument("--bringup", type=Path, default=None, help="bringup description YAML")
    up_parser.add_argument("--log-dir", type=Path, default=DEFAULT_LOG_ROOT, help="where node logs go")
    up_parser.add_argument(
        "--start", action="store_true", help="once up: plan the planner's motion, enable the driver, start playback"
    )
    up_parser.add_argument("--separate", action="store_true", help=SEPARATE_HELP)
    up_parser.add_argument("--no-record", action="store_true", help="run without the recorder (no bag)")
    exp = commands.add_parser("experiment", help="plan, run on the simulated robot, record and report a motion")
    exp.add_argument("motion", help="motion name (rh5-plan --list)")
    exp.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="motion parameter override")
    exp.add_argument("--sim", choices=["kinematic", "physics"], default="physics", help="simulated hardware")
    exp.add_argument("--out", type=Path, default=Path("out"), help="output root (trajectories/, experiments/)")
    exp.add_argument("--replan", action="store_true", help="plan again even if a cached trajectory exists")
    exp.add_argument("--hold", type=float, default=1.0, help="seconds to keep holding after the motion ends")
    exp.add_argument("--bringup", type=Path, default=None, help="bringup description YAML")
    exp.add_argument("--no-report", action="store_true", help="record only")
    exp.add_argument("--separate", action="store_true", help=SEPARATE_HELP)
    exp.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NODE.KEY=VALUE",
        help="node parameter, e.g. stabilizer.balance_correction=true",
    )
    for sub in (up_parser, exp):
        sub.add_argument("--domain-id", type=int, default=None, help=DOMAIN_HELP)
    add_bag_parser(commands)
    rep = commands.add_parser("report", help="write the report of a recorded experiment bag")
    rep.add_argument("bag", type=Path, help="rosbag2 folder")
    rep.add_argument("--joints", default="", help="extra joints to plot, comma separated")
    rep.add_argument("--out", type=Path, default=None, help="report folder (default: next to the bag)")
    return parser


def up_command(args: argparse.Namespace) -> int:
    """``rh5 up``: check the arguments (exit 2 with the reason), then run the suite."""
    if args.duration is not None and args.duration <= 0:
        print("rh5 up: --duration must be positive", file=sys.stderr)
        return 2
    try:
        domain = chosen_domain_id(args.domain_id)
    except ValueError as err:
        print(f"rh5 up: {err}", file=sys.stderr)
        return 2
    bringup = replace(load_bringup(args.bringup).resolved(sim=args.sim), composed=not args.separate)
    if args.no_record:
        bringup = bringup.without("recorder")
    return up(bringup, args.duration, args.log_dir, start=args.start, domain=domain)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``rh5``."""
    args = build_parser().parse_args(argv)
    commands = {"up": up_command, "experiment": experiment, "report": report, "bag": bag_command}
    return commands[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
