"""Loop timing of the stabilizer node while it plays a trajectory (targets: >= 999.5 Hz, p99 jitter <= 100 us).

The node runs as its own process; this script feeds it 1 kHz joint_states (a robot that
follows its commands perfectly), starts playback of a long trajectory, and after the run
prints the node's own loop statistics (from its exit summary) and the command rate seen here.

    .venv/bin/python bench/stabilizer.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from rh5_bringup.orchestration.cli import call_trigger
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, joint_trajectory_to_msg
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop
from rh5_msgs_py.ros_env import DomainLease, suite_environment


def main() -> None:
    """Run the stabilizer for the given time and print its loop timing."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_stabilizer"
    os.environ.update(suite_environment(lease.domain_id, log_dir))  # read by rclpy.init below
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_stabilizer")
    pose = {"q": np.zeros(NUM_JOINTS)}
    received: list[int] = []
    state_codec = JointStateCodec(JOINT_NAMES)
    command_codec = JointStateCodec(JOINT_NAMES)

    def on_command(msg: JointState) -> None:
        received.append(time.monotonic_ns())
        pose["q"] = command_codec.decode(msg).position

    node.create_subscription(JointState, interfaces.JOINT_COMMANDS.name, on_command, interfaces.STREAM_QOS)
    states = node.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
    trajectories = node.create_publisher(JointTrajectory, interfaces.PLANNED_TRAJECTORY.name, interfaces.LATCHED_QOS)
    feeder = DeadlineLoop(
        1000.0, lambda _n, _p: states.publish(state_codec.encode(pose["q"], np.zeros(NUM_JOINTS))), "bench-feeder"
    )
    t = np.arange(0.0, args.seconds + 5.0, 0.01)
    q = 0.1 * np.sin(2 * np.pi * 0.5 * t)[:, None] * np.ones(NUM_JOINTS)
    spec = NodeSpec("stabilizer", "rh5_joint_stabilizer", "stabilizer_node", {"state_timeout_s": 0.05})
    with SuiteRun(Bringup("", (spec,)), log_dir, lease.domain_id) as run:
        assert not wait_for_nodes(node, {"stabilizer"}), "stabilizer never appeared"
        feeder.start()
        trajectories.publish(joint_trajectory_to_msg(JOINT_NAMES, t, q))
        ok, message = call_trigger(node, "/stabilizer/start")
        print(f"start: {ok} ({message})")
        received.clear()
        end = time.monotonic() + args.seconds
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
        feeder.stop()
    summary = run.processes[0].summary() or {}
    node.destroy_node()
    rclpy.try_shutdown()
    lease.release()
    loop = summary.get("loop", {})
    print(f"stabilizer loop over its last {min(loop.get('cycles', 0), 1000)} cycles (of {loop.get('cycles')}):")
    print(f"  rate {loop.get('rate_hz', 0):.2f} Hz (target >= 999.5)")
    print(
        f"  period p50 {loop.get('period_p50_us', 0):.1f} us, p99 {loop.get('period_p99_us', 0):.1f} us, "
        f"max {loop.get('period_max_us', 0):.1f} us (target: none over 2000 us)"
    )
    print(
        f"  jitter p50 {loop.get('jitter_p50_us', 0):.1f} us, p99 {loop.get('jitter_p99_us', 0):.1f} us "
        f"(target <= 100), max {loop.get('jitter_max_us', 0):.1f} us; deadline misses {loop.get('deadline_misses')}"
    )
    stamps = np.array(received)
    if len(stamps) > 1:
        rate = (len(stamps) - 1) / ((stamps[-1] - stamps[0]) / 1e9)
        print(f"  joint_commands received here: {len(stamps)} in {args.seconds:g} s ({rate:.1f} Hz through DDS)")
    print(f"  final state: {summary.get('state')}, events: {summary.get('events')}")


if __name__ == "__main__":
    main()
