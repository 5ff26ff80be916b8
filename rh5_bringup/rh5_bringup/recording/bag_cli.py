"""``rh5 bag info BAG`` and ``rh5 bag recover BAG``: describe a bag, and complete one whose recorder was killed.

``recover`` does what ``ros2 bag reindex`` does for a rosbag2 MCAP bag: it keeps every whole chunk,
writes the summary, footer and ``rosbag2`` metadata record the killed recorder never wrote and
rewrites metadata.yaml, so rosbags and mcap's seeking reader accept the bag. Exit codes: 0 done,
2 not a readable bag (the reason on stderr).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rh5_bringup.recording import BagRecoveryError, format_bag_info, read_bag_info, recover_bag

__all__ = ["add_bag_parser", "bag_command"]


def add_bag_parser(commands: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``bag`` with its ``info`` and ``recover`` subcommands to ``rh5``'s subparsers."""
    bag = commands.add_parser("bag", help="describe a bag, or complete one whose recorder was killed")
    actions = bag.add_subparsers(dest="bag_command", required=True)
    info = actions.add_parser("info", help="files, compression, duration, messages per topic (read from the MCAP)")
    info.add_argument("bag", type=Path, help="rosbag2 folder")
    recover = actions.add_parser(
        "recover", help="make a killed recording readable by every reader (as ros2 bag reindex); keeps whole chunks"
    )
    recover.add_argument("bag", type=Path, help="rosbag2 folder")


def bag_command(args: argparse.Namespace) -> int:
    """Run ``rh5 bag info`` or ``rh5 bag recover``."""
    try:
        if args.bag_command == "info":
            print(format_bag_info(read_bag_info(args.bag)))
            return 0
        result = recover_bag(args.bag)
    except (BagRecoveryError, OSError) as err:
        print(f"rh5 bag {args.bag_command}: {err}", file=sys.stderr)
        return 2
    if not result.recovered:
        print(f"rh5 bag recover: {result.bag} is complete already ({result.message_count} messages), unchanged")
        return 0
    print(
        f"rh5 bag recover: {result.bag}: kept {result.message_count} messages in {result.chunk_count} whole chunks, "
        f"discarded {result.discarded_bytes} bytes of the chunk being written"
    )
    for topic, count in result.counts.items():
        print(f"  {topic}: {count}")
    return 0
