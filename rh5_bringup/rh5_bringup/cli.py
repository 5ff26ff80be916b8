"""The ``rh5`` command line: start the suite (``rh5 up``) and, later, run experiments and reports."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from datetime import datetime
from pathlib import Path
from types import FrameType
from typing import Any

from rh5_bringup.launcher import Bringup, SuiteRun, load_bringup, wait_for_nodes

DEFAULT_LOG_ROOT = Path(".ros") / "log"


def _run_dir(root: Path) -> Path:
    return root / datetime.now().strftime("rh5_%Y%m%d_%H%M%S_%f")


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


def call_trigger(node: Any, service: str, timeout_s: float = 10.0) -> tuple[bool, str]:
    """Call a std_srvs/Trigger service, retrying while it refuses, until it succeeds or time runs out."""
    from std_srvs.srv import Trigger  # noqa: PLC0415

    return _call_until_success(node, Trigger, service, Trigger.Request(), timeout_s)


def call_set_bool(node: Any, service: str, value: bool, timeout_s: float = 10.0) -> tuple[bool, str]:
    """Call a std_srvs/SetBool service, retrying while it refuses, until it succeeds or time runs out."""
    from std_srvs.srv import SetBool  # noqa: PLC0415

    return _call_until_success(node, SetBool, service, SetBool.Request(data=value), timeout_s)


def _call_until_success(node: Any, kind: Any, service: str, request: Any, timeout_s: float) -> tuple[bool, str]:
    import rclpy  # noqa: PLC0415

    client = node.create_client(kind, service)
    deadline = time.monotonic() + timeout_s
    answer = (False, f"{service} not available")
    try:
        while time.monotonic() < deadline:
            if not client.wait_for_service(timeout_sec=0.2):
                continue
            future = client.call_async(request)
            rclpy.spin_until_future_complete(node, future, timeout_sec=max(0.1, deadline - time.monotonic()))
            if future.done():
                answer = (future.result().success, future.result().message)
                if answer[0]:
                    return answer
            time.sleep(0.2)
        return answer
    finally:
        node.destroy_client(client)


def up(bringup: Bringup, duration_s: float | None, log_root: Path, start: bool = False) -> int:
    """Start the suite, wait until every node is in the graph, run, stop cleanly and report."""
    run = SuiteRun(bringup, _run_dir(log_root))
    stop_requested = False

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        nonlocal stop_requested
        stop_requested = True

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    os.environ.update(run.env)  # the launcher's own graph observer joins the run's domain
    import rclpy  # noqa: PLC0415 (after the environment is set)

    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    observer = rclpy.create_node("rh5_launcher")
    try:
        run.start()
        print(f"rh5 up: ROS_DOMAIN_ID={run.domain_id}, logs in {run.log_dir}", flush=True)
        names = {n.name for n in bringup.nodes}
        namespace = "/" + bringup.namespace.strip("/") if bringup.namespace else "/"
        missing = wait_for_nodes(observer, names, namespace)
        if missing:
            print(f"rh5 up: never appeared in the ROS graph: {sorted(missing)}", file=sys.stderr)
        else:
            print(f"rh5 up: {len(names)} nodes running: {', '.join(sorted(names))}", flush=True)
            if start:
                print("rh5 up: planning the planner's motion ...", flush=True)
                _, message = call_trigger(observer, f"{namespace.rstrip('/')}/planner/plan", timeout_s=120.0)
                print(f"rh5 up: planner plan: {message}", flush=True)
                _, message = call_set_bool(observer, f"{namespace.rstrip('/')}/driver/enable", True)
                print(f"rh5 up: driver enable: {message}", flush=True)
                _, message = call_trigger(observer, f"{namespace.rstrip('/')}/stabilizer/start")
                print(f"rh5 up: stabilizer start: {message}", flush=True)
        deadline = None if duration_s is None else time.monotonic() + duration_s
        while not stop_requested and not run.exited() and (deadline is None or time.monotonic() < deadline):
            time.sleep(0.05)
        crashed = [p.spec.name for p in run.exited()]
        if crashed:
            print(f"rh5 up: stopped on their own: {crashed}", file=sys.stderr)
    finally:
        exit_codes = run.stop()
        observer.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print(format_report(run, exit_codes), flush=True)
    return 0 if not missing and all(code == 0 for code in exit_codes.values()) else 1


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
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``rh5``."""
    args = build_parser().parse_args(argv)
    if args.command == "up":
        if args.duration is not None and args.duration <= 0:
            print("rh5 up: --duration must be positive", file=sys.stderr)
            return 2
        bringup = load_bringup(args.bringup).resolved(sim=args.sim)
        return up(bringup, args.duration, args.log_dir, start=args.start)
    return 2


if __name__ == "__main__":
    sys.exit(main())
