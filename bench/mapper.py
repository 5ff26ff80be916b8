"""Benchmark of the joint <-> actuator mapper: per-sample maps, batch maps, and the node at 1 kHz.

Prints figures and ratios measured in this one run (targets from the mapper issue):
whole-robot joint -> actuator per sample <= 50 us, actuator -> joint (warm-started FK)
<= 100 us, 10,000-sample batch <= 100 ms, each beside a naive per-sample Python loop;
then the mapper node fed 1 kHz joint_commands through a loopback for a few seconds.

    .venv/bin/python bench/mapper.py [--node-seconds 5]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.mapping import RobotMapper, robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec
from rh5_msgs_py.names import ACTUATOR_INDEX, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.ros_env import DomainLease, suite_environment

BATCH = 10_000


def timed_us(fn: Callable[[], object], repeat: int) -> np.ndarray:
    """Wall time of each of ``repeat`` calls, in microseconds."""
    out = np.empty(repeat)
    for k in range(repeat):
        start = time.perf_counter_ns()
        fn()
        out[k] = (time.perf_counter_ns() - start) / 1e3
    return out


def trajectory(n: int) -> tuple[np.ndarray, ...]:
    """A smooth whole-body motion around a bent-knee pose, sampled at 1 kHz."""
    t = np.arange(n)[:, None] * 1e-3
    q0 = np.zeros(NUM_JOINTS)
    for side in "LR":
        q0[JOINT_INDEX[f"L{side}Knee"]], q0[JOINT_INDEX[f"L{side}Hip3"]] = 0.6, -0.3
    omega = np.linspace(1.0, 4.0, NUM_JOINTS)
    amplitude = 0.1
    q = q0 + amplitude * np.sin(omega * t)
    v = amplitude * omega * np.cos(omega * t)
    a = -amplitude * omega**2 * np.sin(omega * t)
    tau = 30.0 * np.cos(omega * t)
    return q, v, a, tau


def naive_to_actuators(mapper: RobotMapper, q: np.ndarray, v: np.ndarray, a: np.ndarray, tau: np.ndarray) -> None:
    """The straightforward way: every submechanism separately, every product with Python-level indexing."""
    out = np.zeros((4, NUM_JOINTS))
    for model in mapper.submechanisms:
        jj = [JOINT_INDEX[j] for j in model.joints]
        aa = [ACTUATOR_INDEX[x] for x in model.actuators]
        y, yd = q[jj], v[jj]
        jac = model.jacobian(y)
        out[0, aa] = model.inverse(y)
        out[1, aa] = jac @ yd
        out[2, aa] = jac @ a[jj] + model.bias(y, yd)
        out[3, aa] = np.linalg.solve(jac.T, tau[jj])


def bench_maps(mapper: RobotMapper) -> None:
    """Per-sample and batch maps, with their naive counterparts."""
    q, v, a, tau = trajectory(BATCH)
    actuators = mapper.to_actuators(q, v, a, tau)
    k = 500
    single = timed_us(lambda: mapper.to_actuators(q[k], v[k], a[k], tau[k]), 2000)
    naive_single = timed_us(lambda: naive_to_actuators(mapper, q[k], v[k], a[k], tau[k]), 2000)
    l, ld, f = actuators.position, actuators.velocity, actuators.effort
    fk = timed_us(lambda: mapper.to_joints(l[k], ld[k], f[k], q_guess=q[k - 1]), 2000)
    fk_cold = timed_us(lambda: mapper.to_joints(l[k], ld[k], f[k]), 500)
    batch_ms = timed_us(lambda: mapper.to_actuators(q, v, a, tau), 10) / 1e3
    batch_fk_ms = timed_us(lambda: mapper.to_joints(l, ld, f, q_guess=np.roll(q, 1, axis=0)), 5) / 1e3
    start = time.perf_counter()
    for i in range(BATCH):
        mapper.to_actuators(q[i], v[i], a[i], tau[i])
    loop_ms = (time.perf_counter() - start) * 1e3

    def row(name: str, values: np.ndarray, unit: str, target: float, naive: float | None = None) -> None:
        median = float(np.median(values))
        ratio = f"  naive/this {naive / median:5.1f}x" if naive else ""
        verdict = "PASS" if median <= target else "MISS"
        print(
            f"{name:<46} median {median:9.1f} {unit}  p99 {np.percentile(values, 99):9.1f} {unit}"
            f"  target <= {target:g} {unit}: {verdict}{ratio}"
        )

    print(f"whole-robot maps, {NUM_JOINTS} joints, numpy {np.__version__}")
    row("joint -> actuator (q, v, a, tau), 1 sample", single, "us", 50, float(np.median(naive_single)))
    row("actuator -> joint (l, ld, f), warm-started FK", fk, "us", 100)
    row("actuator -> joint, cold-started FK", fk_cold, "us", 100)
    row(f"joint -> actuator, batch of {BATCH}", batch_ms, "ms", 100, loop_ms)
    row(f"actuator -> joint, batch of {BATCH}", batch_fk_ms, "ms", 200)
    print(
        f"  (naive single: per-submechanism loop, median {np.median(naive_single):.1f} us; "
        f"naive batch: {BATCH} single-sample calls, {loop_ms:.0f} ms)"
    )


def bench_node(seconds: float) -> None:
    """Feed the mapper node 1 kHz joint_commands through a loopback and count what comes back."""
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_mapper"
    os.environ.update(suite_environment(lease.domain_id, log_dir))  # read by rclpy.init below
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_mapper")
    received = {"actuator_commands": 0, "joint_states": 0}
    states = node.create_publisher(JointState, interfaces.ACTUATOR_STATES.name, interfaces.STREAM_QOS)

    def on_commands(msg: JointState) -> None:
        received["actuator_commands"] += 1
        states.publish(msg)

    def on_states(_msg: JointState) -> None:
        received["joint_states"] += 1

    node.create_subscription(JointState, interfaces.ACTUATOR_COMMANDS.name, on_commands, interfaces.STREAM_QOS)
    node.create_subscription(JointState, interfaces.JOINT_STATES.name, on_states, interfaces.STREAM_QOS)
    commands = node.create_publisher(JointState, interfaces.JOINT_COMMANDS.name, interfaces.STREAM_QOS)
    codec = JointStateCodec(JOINT_NAMES)
    q, v, _, tau = trajectory(int(seconds * 1000) + 1)
    bringup = Bringup("", (NodeSpec("mapper", "rh5_hyrodyn_mapper", "mapper_node", {}),))
    with SuiteRun(bringup, log_dir, lease.domain_id) as run:
        assert not wait_for_nodes(node, {"mapper"}), "mapper never appeared"
        time.sleep(1.0)  # let discovery match every endpoint
        sent, next_tick = 0, time.perf_counter_ns()
        for k in range(len(q)):
            next_tick += 1_000_000
            commands.publish(codec.encode(q[k], v[k], tau[k], stamp_ns=time.time_ns()))
            sent += 1
            while time.perf_counter_ns() < next_tick:
                rclpy.spin_once(node, timeout_sec=0)
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)
    summary = run.processes[0].summary() or {}
    node.destroy_node()
    rclpy.try_shutdown()
    lease.release()
    print(f"\nmapper node at 1 kHz for {seconds:g} s (loopback in this process): sent {sent} joint_commands")
    for topic, count in received.items():
        print(f"  received {topic}: {count} ({100 * count / sent:.1f} %)")
    for topic, lat in summary.get("latency_us", {}).items():
        print(
            f"  node processing of {topic}: p50 {lat['p50_us']:.0f} us, p99 {lat['p99_us']:.0f} us, "
            f"max {lat['max_us']:.0f} us (budget 1000 us per message)"
        )
    print(f"  rejected: {summary.get('rejected')}, clamped: {summary.get('clamped')}")


def main() -> None:
    """Run the map benchmarks, then the node benchmark."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--node-seconds", type=float, default=5.0, help="0 skips the node benchmark")
    args = parser.parse_args()
    bench_maps(robot_mapper())
    if args.node_seconds > 0:
        bench_node(args.node_seconds)


if __name__ == "__main__":
    main()
