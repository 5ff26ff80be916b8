"""``python -m rh5_bringup.analysis BAG [--joints a,b] [--out DIR]``: write an experiment report.

Exit codes: 0 report written, 2 the input is not a readable bag or a joint name is unknown.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Final

from rh5_bringup.analysis import ReportError, build_report

EXIT_BAD_INPUT: Final = 2


def parser() -> argparse.ArgumentParser:
    """The command line (also used by ``rh5 report``)."""
    p = argparse.ArgumentParser(
        prog="python -m rh5_bringup.analysis", description="Write PNG plots and a Markdown summary of a recorded bag."
    )
    p.add_argument("bag", type=Path, help="rosbag2 folder (metadata.yaml + MCAP) recorded by the suite")
    p.add_argument(
        "--joints", default="", help="comma-separated joints or actuators to plot as well, e.g. LLKnee,LRKnee"
    )
    p.add_argument("--out", type=Path, default=None, help="report folder (default: <bag>_report next to the bag)")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit code."""
    args = parser().parse_args(argv)
    joints = [j.strip() for j in args.joints.split(",") if j.strip()]
    try:
        report = build_report(args.bag, args.out, joints)
    except ReportError as err:
        print(f"report: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for line in report.verdicts:
        print(line)
    print(f"report: {report.markdown}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
