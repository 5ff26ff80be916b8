"""The driver's 1 kHz loop against the simulated-hardware node, beside an rclpy 1 kHz timer, in one run.

Targets (hardware-layer issue): loop >= 999.5 Hz, period jitter p99 <= 100 us, no period
over 2 ms; codec >= 200k frames/s; command-to-board latency p99 <= 2 ms (here measured
command -> board -> telemetry back, i.e. the full round trip, which is stricter).

    .venv/bin/python bench/driver.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import os
import socket
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions

from rh5_bringup.hardware.driver_node import actuator_limits
from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.codec import FrameDecoder, encode_frame
from rh5_bringup.hardware.rig import DriverLoop, sine_centre
from rh5_bringup.hardware.transports import open_transport
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py.names import NUM_JOINTS
from rh5_msgs_py.realtime import LoopTimer
from rh5_msgs_py.ros_env import DomainLease, suite_environment


def codec_throughput(frames: int = 100_000) -> float:
    """Encode + decode of 40-byte payloads, frames per second."""
    payload = bytes(range(40))
    decoder = FrameDecoder()
    start = time.perf_counter()
    for k in range(0, frames, 32):
        decoder.feed(b"".join(encode_frame(0x01, 0x10 + i, k & 0xFF, payload) for i in range(32)))
    return frames / (time.perf_counter() - start)


def rclpy_timer_stats(seconds: float) -> dict[str, float]:
    """Rate and jitter of an rclpy 1 kHz timer (what the deadline loop replaces)."""
    node = rclpy.create_node("bench_rclpy_timer")
    timer = LoopTimer(1_000_000, window=int(seconds * 1000) + 10)
    node.create_timer(0.001, lambda: timer.record(time.monotonic_ns()))
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
    node.destroy_node()
    return timer.stats().as_dict()


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def show(name: str, stats: dict[str, float]) -> None:
    print(
        f"{name:<28} rate {stats['rate_hz']:8.2f} Hz  period p50 {stats['period_p50_us']:7.1f} p99 "
        f"{stats['period_p99_us']:7.1f} max {stats['period_max_us']:8.1f} us  jitter p50 {stats['jitter_p50_us']:6.1f} "
        f"p99 {stats['jitter_p99_us']:7.1f} max {stats['jitter_max_us']:8.1f} us  misses {stats['deadline_misses']}"
    )


def main() -> None:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    lease = DomainLease()
    log_dir = Path(".ros") / "log" / "bench_driver"
    os.environ.update(suite_environment(lease.domain_id, log_dir))  # read by rclpy.init below
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    print(f"codec: {codec_throughput():,.0f} frames/s encode+decode (target >= 200,000)")
    port = free_port()
    board_map = load_board_map()
    limits = actuator_limits()
    centre = sine_centre(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position, limits)
    spec = NodeSpec("sim_hardware", "rh5_bringup", "sim_hardware_node", {"listen_port": port})
    observer = rclpy.create_node("bench_driver")
    with SuiteRun(Bringup("", (spec,)), log_dir, lease.domain_id) as run:
        assert not wait_for_nodes(observer, {"sim_hardware"}), "sim_hardware never appeared"
        link = open_transport(
            "udp", local=("127.0.0.1", 0), remote=("127.0.0.1", port), receivers=[board_map.pc_address]
        )
        rig = DriverLoop(board_map, link, limits, centre, seconds_kept=args.seconds + 5)
        rig.loop.timer = LoopTimer(rig.loop.period_ns, window=int(args.seconds * 1000) + 10)
        rig.loop.start()
        time.sleep(0.3)
        print(f"enable: {rig.core.enable(True)}")
        time.sleep(args.seconds)
        rig.loop.stop()
        link.shutdown()
        timer_stats = rclpy_timer_stats(min(args.seconds, 10.0))
    observer.destroy_node()
    rclpy.try_shutdown()
    lease.release()
    summary = run.processes[0].summary() or {}
    print(f"\n{args.seconds:g} s, 32 boards, UDP on 127.0.0.1 (whole window):")
    show("driver deadline loop", rig.loop.stats().as_dict())
    show("rclpy 1 kHz timer (10 s)", timer_stats)
    show("sim boards loop (its last 1 s)", summary.get("loop", {}))
    latency = rig.core.latency.percentiles_us()
    print(
        f"command -> board -> telemetry: p50 {latency['p50_us']:.0f} us, p99 {latency['p99_us']:.0f} us, "
        f"max {latency['max_us']:.0f} us (last 2000 echoes; target p99 <= 2000)"
    )
    errors = rig.tracking_error()
    print(
        f"tracking of the 0.5 Hz sine: max error {errors.max() * 1e3:.3f} mm|mrad; safe hold: "
        f"{rig.core.safe_hold_reason or 'never'}; counts {dict(rig.core.counts)}"
    )


if __name__ == "__main__":
    main()
