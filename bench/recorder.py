"""CPU cost, bag size and completeness of the recorder node while three 1 kHz JointState streams are recorded.

The recorder runs as its own process (recording joint_states, joint_commands and actuator_states),
once with zstd chunks (the default) and once uncompressed; this script publishes the three streams
at 1 kHz (32 joints, position/velocity/effort of a slow motion with sensor noise, like the suite's
loops) for ``--seconds`` each time,
samples the recorder's CPU time from /proc while it records, stops it with SIGINT and reads the bag
back with rosbags. Prints per mode: the recorder's CPU share of one core, the bag size per second of
recorded stream time (the bag's own log-time span; the streams' clock is the wall clock here, the
simulated second of a suite that runs in real time), and messages sent / received / in the bag / lost.

    .venv/bin/python bench/recorder.py [--seconds 10] [--compression zstd none] [--data motion|held]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from rosbags.highlevel import AnyReader

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_bringup.recording import read_bag_info
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop
from rh5_msgs_py.ros_env import DomainLease, suite_environment

STREAMS = (interfaces.JOINT_STATES, interfaces.JOINT_COMMANDS, interfaces.ACTUATOR_STATES)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class Result:
    """One recording: CPU share, bag size and span, and per stream sent / received / in the bag."""

    compression: str
    cpu_share: float
    wall_s: float
    bag_bytes: int
    span_s: float
    sent: dict[str, int]
    received: dict[str, int]
    in_bag: dict[str, int]
    summary: dict[str, Any]
    loop: dict[str, Any]

    @property
    def lost(self) -> int:
        """Messages sent but not in the bag."""
        return sum(n - self.in_bag.get(name, 0) for name, n in self.sent.items())


class Streams:
    """The three 1 kHz streams, published from a deadline loop of this process."""

    def __init__(self, node: Any, *, held: bool = False) -> None:
        self.node = node
        self.held = held
        self.publishers = [node.create_publisher(rclpy_type(t), t.name, t.qos) for t in STREAMS]
        self.codecs = [JointStateCodec(JOINT_NAMES) for _ in STREAMS]
        self.sent = [0] * len(STREAMS)
        self._rng = np.random.default_rng(0)
        self._phase = np.arange(NUM_JOINTS, dtype=float)

    def tick(self, now_ns: int, _period: int) -> None:
        """Publish one message per stream: a slow motion of every joint plus sensor noise, as measured data is
        (all-zero arrays would compress far better than any recording; the compression ratio must be honest)."""
        t = 0.0 if self.held else now_ns * 1e-9
        motion = 0.3 * np.sin(np.pi * t + self._phase)
        if self.held:  # a robot holding still: the same values every cycle
            for k, (publisher, codec) in enumerate(zip(self.publishers, self.codecs, strict=True)):
                publisher.publish(codec.encode(motion, 0.0 * motion, 20.0 * motion, stamp_ns=time.time_ns()))
                self.sent[k] += 1
            return
        for k, (publisher, codec) in enumerate(zip(self.publishers, self.codecs, strict=True)):
            q = motion + self._rng.normal(0.0, 1e-4, NUM_JOINTS)
            qd = 0.3 * np.pi * np.cos(np.pi * t + self._phase) + self._rng.normal(0.0, 1e-3, NUM_JOINTS)
            tau = 20.0 * motion + self._rng.normal(0.0, 0.05, NUM_JOINTS)
            publisher.publish(codec.encode(q, qd, tau, stamp_ns=time.time_ns()))
            self.sent[k] += 1


def record(node: Any, domain_id: int, log_dir: Path, compression: str, seconds: float, *, held: bool) -> Result:
    """Record the streams for ``seconds`` with ``compression`` (zstd or none) and read the bag back."""
    streams = Streams(node, held=held)
    with tempfile.TemporaryDirectory(prefix="rh5_bench_recorder_") as tmp:
        bag = Path(tmp) / "bag"
        parameters = {"output": str(bag), "topics": [t.name for t in STREAMS], "compression": compression}
        spec = NodeSpec("recorder", "rh5_bringup", "recorder_node", parameters)
        with SuiteRun(Bringup("", (spec,)), log_dir / compression, domain_id) as run:
            assert wait_for_nodes(node, {"recorder"}) == set(), "the recorder did not start"
            while any(p.get_subscription_count() == 0 for p in streams.publishers):
                rclpy.spin_once(node, timeout_sec=0.05)
            pid = run.processes[0].process.pid
            loop = DeadlineLoop(1000.0, streams.tick, "bench-publisher")
            cpu0, wall0 = cpu_seconds(pid), time.monotonic()
            loop.start()
            time.sleep(seconds)
            loop.stop()
            time.sleep(0.3)  # in flight
            cpu1, wall1 = cpu_seconds(pid), time.monotonic()
        summary = run.processes[0].summary() or {}
        with AnyReader([bag]) as reader:
            in_bag = {c.topic.lstrip("/"): c.msgcount for c in reader.connections}
        info = read_bag_info(bag)
        size = sum(f.stat().st_size for f in bag.iterdir())
    names = [t.name for t in STREAMS]
    return Result(
        compression,
        (cpu1 - cpu0) / (wall1 - wall0),
        wall1 - wall0,
        size,
        (info.end_ns - info.start_ns) / 1e9,
        dict(zip(names, streams.sent, strict=True)),
        {name: summary.get("seen", {}).get(name, 0) for name in names},
        in_bag,
        summary,
        loop.stats().as_dict(),
    )


def main() -> None:
    """Record three 1 kHz streams per compression mode; print CPU share, bag size per second and losses."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--compression", nargs="+", choices=["zstd", "none"], default=["zstd", "none"])
    parser.add_argument(
        "--data",
        choices=["motion", "held"],
        default="motion",
        help="motion: every value moves and carries sensor noise (the hardest to compress); held: constant values",
    )
    args = parser.parse_args()
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_recorder"
    os.environ.update(suite_environment(lease.domain_id, log_dir))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_recorder")
    try:
        held = args.data == "held"
        results = [record(node, lease.domain_id, log_dir, mode, args.seconds, held=held) for mode in args.compression]
    finally:
        node.destroy_node()
        rclpy.shutdown()
        lease.release()
    for result in results:
        print(f"compression {result.compression}:")
        print(f"  recorder CPU while recording 3 x 1 kHz: {100 * result.cpu_share:.1f} % of one core")
        print(
            f"  bag {result.bag_bytes / 1e6:.2f} MB for {result.span_s:.2f} s of streams: "
            f"{result.bag_bytes / 1e6 / result.span_s:.3f} MB per second"
        )
        for name, sent in result.sent.items():
            print(f"  {name}: sent {sent}, received {result.received[name]}, in bag {result.in_bag.get(name)}")
        summary = result.summary
        print(f"  lost {result.lost}; dropped {summary.get('dropped')}, sequence gaps {summary.get('sequence_gaps')}")
        print(f"  max queued {summary.get('max_pending')}; publisher loop {result.loop}")
    sizes = {r.compression: r.bag_bytes / r.span_s for r in results}
    if {"zstd", "none"} <= set(sizes):
        print(f"zstd bag / uncompressed bag, per second: {sizes['zstd'] / sizes['none']:.3f}")


def rclpy_type(topic: interfaces.Topic) -> type:
    """The message class of a topic."""
    return interfaces.message_class(topic.type)


if __name__ == "__main__":
    main()
