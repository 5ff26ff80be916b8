"""CPU cost and completeness of the recorder node while three 1 kHz JointState streams are recorded.

The recorder runs as its own process (recording joint_states, joint_commands and actuator_states);
this script publishes the three streams at 1 kHz (32 joints, position/velocity/effort, like the
suite's loops) for ``--seconds``, samples the recorder's CPU time from /proc while it records,
stops it with SIGINT and reads the bag back with rosbags. Prints the recorder's CPU share of one
core, messages sent / received / recorded per topic, and the bag size.

    .venv/bin/python bench/recorder.py [--seconds 10]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from rosbags.highlevel import AnyReader

from rh5_bringup.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
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


def main() -> None:
    """Record three 1 kHz streams for the given time; print CPU share and counts."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args()
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_recorder"
    os.environ.update(suite_environment(lease.domain_id, log_dir))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_recorder")
    publishers = [node.create_publisher(rclpy_type(t), t.name, t.qos) for t in STREAMS]
    codecs = [JointStateCodec(JOINT_NAMES) for _ in STREAMS]
    sent = [0] * len(STREAMS)
    q = np.zeros(NUM_JOINTS)

    def tick(_now_ns: int, _period: int) -> None:
        for k, (publisher, codec) in enumerate(zip(publishers, codecs, strict=True)):
            q[0] = sent[k]
            publisher.publish(codec.encode(q, q, q, stamp_ns=time.time_ns()))
            sent[k] += 1

    with tempfile.TemporaryDirectory(prefix="rh5_bench_recorder_") as tmp:
        bag = Path(tmp) / "bag"
        parameters = {"output": str(bag), "topics": [t.name for t in STREAMS]}
        spec = NodeSpec("recorder", "rh5_bringup", "recorder_node", parameters)
        with SuiteRun(Bringup("", (spec,)), log_dir, lease.domain_id) as run:
            assert wait_for_nodes(node, {"recorder"}) == set(), "the recorder did not start"
            while any(p.get_subscription_count() == 0 for p in publishers):
                rclpy.spin_once(node, timeout_sec=0.05)
            pid = run.processes[0].process.pid
            loop = DeadlineLoop(1000.0, tick, "bench-publisher")
            loop.start()
            time.sleep(1.0)  # warm-up
            cpu0, wall0 = cpu_seconds(pid), time.monotonic()
            time.sleep(args.seconds)
            cpu1, wall1 = cpu_seconds(pid), time.monotonic()
            loop.stop()
            time.sleep(0.3)
        summary = run.processes[0].summary() or {}
        with AnyReader([bag]) as reader:
            recorded = {c.topic.lstrip("/"): c.msgcount for c in reader.connections}
        size = sum(f.stat().st_size for f in bag.iterdir())
    node.destroy_node()
    rclpy.shutdown()
    lease.release()
    share = (cpu1 - cpu0) / (wall1 - wall0)
    print(f"recorder CPU while recording 3 x 1 kHz: {100 * share:.1f} % of one core ({wall1 - wall0:.1f} s)")
    print(f"publisher loop: {loop.stats().as_dict()}")
    for k, topic in enumerate(STREAMS):
        name = topic.name
        seen = summary.get("seen", {}).get(name)
        print(f"  {name}: sent {sent[k]}, received {seen}, in bag {recorded.get(name)}")
    print(f"dropped {summary.get('dropped')}, sequence gaps {summary.get('sequence_gaps')}, ", end="")
    print(f"max queued {summary.get('max_pending')}, bag {size / 1e6:.1f} MB")


def rclpy_type(topic: interfaces.Topic) -> type:
    """The message class of a topic."""
    return interfaces.message_class(topic.type)


if __name__ == "__main__":
    main()
