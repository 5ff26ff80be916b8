"""/tf rate and CPU cost of the state publisher fed 1 kHz joint_states and a 250 Hz base pose.

The node runs as its own process; this script feeds it, counts the /tf messages it receives and reads the
node's CPU time from /proc before and after (user + system), so the figure is the node's whole cost: its
executor, the newest-sample takes and the vectorised transforms.

    .venv/bin/python bench/state_publisher.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop
from rh5_msgs_py.ros_env import DomainLease, suite_environment


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main() -> None:
    """Run the state publisher for the given time and print its /tf rate and CPU share."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--rate", type=float, default=50.0, help="the node's publish_rate_hz")
    parser.add_argument("--no-feed", action="store_true", help="publish no joint_states / base pose (idle cost)")
    args = parser.parse_args()
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_state_publisher"
    os.environ.update(suite_environment(lease.domain_id, log_dir))
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_state_publisher")
    received: list[float] = []
    node.create_subscription(TFMessage, "/tf", lambda _m: received.append(time.monotonic()), interfaces.TF_QOS)
    states = node.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
    poses = node.create_publisher(PoseStamped, interfaces.SIM_BASE_POSE.name, interfaces.STREAM_QOS)
    codec = JointStateCodec(JOINT_NAMES)
    ticks = [0]

    def feed(_now: int, _period: int) -> None:
        ticks[0] += 1
        q = 0.1 * np.sin(ticks[0] * 1e-3) * np.ones(NUM_JOINTS)
        states.publish(codec.encode(q, np.zeros(NUM_JOINTS), stamp_ns=time.time_ns()))
        if ticks[0] % 4 == 0:
            pose = PoseStamped()
            pose.pose.position.z, pose.pose.orientation.w = 0.9, 1.0
            poses.publish(pose)

    feeder = DeadlineLoop(1000.0, feed, "bench-feeder")
    spec = NodeSpec("state_publisher", "rh5_hyrodyn_mapper", "state_publisher_node", {"publish_rate_hz": args.rate})
    with SuiteRun(Bringup("", (spec,)), log_dir, lease.domain_id) as run:
        assert wait_for_nodes(node, {"state_publisher"}) == set()
        if not args.no_feed:
            feeder.start()
        pid = run.processes[0].process.pid
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
        received.clear()
        cpu0, t0 = cpu_seconds(pid), time.monotonic()
        while time.monotonic() - t0 < args.seconds:
            rclpy.spin_once(node, timeout_sec=0.01)
        cpu1, t1 = cpu_seconds(pid), time.monotonic()
        feeder.stop()
    node.destroy_node()
    rclpy.try_shutdown()
    lease.release()
    rate = len(received) / (t1 - t0)
    print(f"/tf: {len(received)} messages in {t1 - t0:.1f} s = {rate:.1f} Hz (target {args.rate:g} Hz)")
    share = 100 * (cpu1 - cpu0) / (t1 - t0)
    print(f"state_publisher CPU: {cpu1 - cpu0:.2f} s in {t1 - t0:.1f} s = {share:.1f} % of one core")


if __name__ == "__main__":
    main()
