"""Micro-benchmark: 32-joint JointState round trip (numpy -> message -> numpy), fast path vs naive.

Not a test. It answers whether conversions fit a 1 kHz loop (target well under 50 us per round trip)
and which float64[] assignment form is fastest for rosidl messages. Run:
    .venv/bin/python bench/msgs_roundtrip.py [--iterations 20000]
"""

from __future__ import annotations

import argparse
import array
import gc
import platform
import time
from collections.abc import Callable

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

from rh5_msgs_py.conversions import JointStateCodec, joint_state_from_msg, joint_state_to_msg
from rh5_msgs_py.names import JOINT_NAMES

TARGET_US = 50.0


def measure(step: Callable[[int], object], iterations: int, warmup: int = 1000) -> np.ndarray:
    """Per-call durations in us of ``step(i)``, timed one by one with perf_counter_ns (gc left on)."""
    for i in range(warmup):
        step(i)
    gc.collect()
    samples = np.empty(iterations, dtype=np.int64)
    clock = time.perf_counter_ns
    for i in range(iterations):
        start = clock()
        step(i)
        samples[i] = clock() - start
    return samples / 1e3


def naive_roundtrip(names: tuple[str, ...], pos: np.ndarray, vel: np.ndarray, eff: np.ndarray, i: int) -> tuple:
    """What one writes without thinking: per-element lists, then list.index per joint on the way back."""
    msg = JointState()
    msg.header.stamp = Time(sec=i // 1_000_000_000, nanosec=i % 1_000_000_000)
    msg.name = list(names)
    msg.position = [float(v) for v in pos]
    msg.velocity = [float(v) for v in vel]
    msg.effort = [float(v) for v in eff]
    out_p, out_v, out_e = np.zeros(len(names)), np.zeros(len(names)), np.zeros(len(names))
    msg_names = list(msg.name)
    for k, name in enumerate(names):
        j = msg_names.index(name)
        out_p[k] = msg.position[j]
        out_v[k] = msg.velocity[j]
        out_e[k] = msg.effort[j]
    return out_p, out_v, out_e


def stats(samples: np.ndarray) -> tuple[float, float, float]:
    """Median, p99, mean."""
    return float(np.median(samples)), float(np.percentile(samples, 99)), float(samples.mean())


def main() -> None:
    """Run every case, print one screen."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    n_iter = args.iterations

    names = JOINT_NAMES
    rng = np.random.default_rng(args.seed)
    pos, vel, eff = rng.normal(size=(3, len(names)))
    codec = JointStateCodec(names)

    # Correctness first: every path gives the same arrays.
    wire_bytes = serialize_message(codec.encode(pos, vel, eff, stamp_ns=1))
    received = deserialize_message(wire_bytes, JointState)
    for got in (codec.decode(received), naive_roundtrip(names, pos, vel, eff, 1)):
        for a, b in zip(got, (pos, vel, eff), strict=True):
            assert np.array_equal(a, b)

    def fast(i: int) -> object:
        return codec.decode(codec.encode(pos, vel, eff, stamp_ns=i))

    def functional(i: int) -> object:
        return joint_state_from_msg(joint_state_to_msg(names, pos, vel, eff, stamp_ns=i), names)

    msg = codec.encode(pos, vel, eff, stamp_ns=1)
    rows: list[tuple[str, np.ndarray]] = [
        ("fast: codec.encode + codec.decode", measure(fast, n_iter)),
        ("  codec.encode only", measure(lambda i: codec.encode(pos, vel, eff, stamp_ns=i), n_iter)),
        ("  codec.decode of a received msg", measure(lambda _: codec.decode(received), n_iter)),
        ("functional: joint_state_to/from_msg", measure(functional, n_iter)),
        ("naive: per-element lists + list.index", measure(lambda i: naive_roundtrip(names, pos, vel, eff, i), n_iter)),
        ("context: serialize_message", measure(lambda _: serialize_message(msg), n_iter)),
        ("context: deserialize_message", measure(lambda _: deserialize_message(wire_bytes, JointState), n_iter)),
    ]
    timer = measure(lambda _: None, n_iter)

    # Forms of assigning one 32-element float64 field (check_fields off, the default).
    target = JointState()
    view_msg = JointState()
    view_msg.position = array.array("d", bytes(8 * len(names)))
    view = np.frombuffer(view_msg.position)
    forms: list[tuple[str, Callable[[int], object]]] = [
        ("msg.position = ndarray", lambda _: setattr(target, "position", pos)),
        ("msg.position = ndarray.tolist()", lambda _: setattr(target, "position", pos.tolist())),
        (
            "msg.position = array('d', x.tobytes())",
            lambda _: setattr(target, "position", array.array("d", pos.tobytes())),
        ),
        ("np.frombuffer(msg.position)[:] = x (in place)", lambda _: view.__setitem__(slice(None), pos)),
    ]
    form_rows = [(label, measure(step, n_iter // 4)) for label, step in forms]

    print(f"JointState round trip, {len(names)} joints, {n_iter} iterations each")
    print(f"Python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}, gc on")
    print(f"timer overhead (subtracted nowhere): median {np.median(timer):.3f} us")
    print()
    print(f"{'case':<50}{'median':>9}{'p99':>9}{'mean':>9}   [us]")
    for label, samples in rows:
        med, p99, mean = stats(samples)
        print(f"{label:<50}{med:9.2f}{p99:9.2f}{mean:9.2f}")
    print()
    print("one float64[32] field assignment")
    for label, samples in form_rows:
        med, p99, mean = stats(samples)
        print(f"  {label:<48}{med:9.2f}{p99:9.2f}{mean:9.2f}")
    print()
    fast_med, fast_p99, _ = stats(rows[0][1])
    naive_med, naive_p99, _ = stats(rows[4][1])
    print(f"ratio naive/fast: median {naive_med / fast_med:.1f}x, p99 {naive_p99 / fast_p99:.1f}x")
    verdict = "PASS" if fast_p99 < TARGET_US else "FAIL"
    print(f"target: round trip p99 < {TARGET_US:.0f} us -> {verdict} ({fast_p99:.2f} us)")


if __name__ == "__main__":
    main()
