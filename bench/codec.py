"""Micro-benchmark: NDLCom codec throughput and payload cost per actuator (target >= 200k frames/s encode+decode).

Not a test. One "cycle" is what the 1 kHz driver handles per millisecond: 32 boards, one 40-byte TELEMETRY payload
each (and one 20-byte COMMAND each). Prints frames/s for framing (encode, decode of a whole cycle fed at once, decode
fed frame by frame as UDP datagrams would, encode+decode) and microseconds per actuator for the payload codecs: first
what runs every millisecond (the driver's command frames, the simulated boards' telemetry encoder and command
decoder, the batch codecs), then the single-board forms, which are the batch codecs on a batch of one (tests, tools).
Run:
    .venv/bin/python bench/codec.py [--seconds 1.0]
"""

from __future__ import annotations

import argparse
import gc
import platform
import random
import time
from collections.abc import Callable

import numpy as np

from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.codec import FrameDecoder, FrameEncoder, encode_frame, fcs16, fcs16_reference
from rh5_bringup.hardware.ndlcom.command_frames import CommandFrames
from rh5_bringup.hardware.ndlcom.payloads import (
    Command,
    CommandMode,
    ErrorFlags,
    StatusFlags,
    Telemetry,
    decode_command,
    decode_telemetry,
    decode_telemetry_many,
    encode_command,
    encode_commands,
    encode_telemetry,
    encode_telemetry_many,
)

TARGET_FRAMES_PER_S = 200_000


def rate(step: Callable[[], object], per_call: int, seconds: float) -> float:
    """Items per second of ``step`` (which handles ``per_call`` items), best of 5 runs of ``seconds`` / 5 each."""
    step()
    gc.collect()
    best = 0.0
    for _ in range(5):
        calls, start = 0, time.perf_counter()
        deadline = start + seconds / 5
        while True:
            for _ in range(20):
                step()
            calls += 20
            now = time.perf_counter()
            if now >= deadline:
                break
        best = max(best, calls * per_call / (now - start))
    return best


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="measuring time per item")
    args = parser.parse_args(argv)
    seconds = args.seconds

    board_map = load_board_map()
    boards = board_map.boards
    n = len(boards)
    rng = random.Random(1)
    telemetry = [
        Telemetry(
            CommandMode.POSITION_FF,
            StatusFlags.ENABLED | StatusFlags.CALIBRATED | StatusFlags.FEED_FORWARD,
            ErrorFlags.NONE,
            rng.randrange(2**32),
            rng.randrange(2**40),
            rng.uniform(b.scaling.position.low, b.scaling.position.high),
            rng.uniform(-0.5, 0.5),
            rng.uniform(-100.0, 100.0),
            rng.uniform(-5.0, 5.0),
            rng.uniform(20.0, 60.0),
        )
        for b in boards
    ]
    payloads = [encode_telemetry(t, b.scaling) for t, b in zip(telemetry, boards, strict=True)]
    pc = board_map.pc_address
    frames = [encode_frame(pc, b.address, 7, p) for b, p in zip(boards, payloads, strict=True)]
    stream = b"".join(frames)
    decoder = FrameDecoder()

    def encode_cycle() -> None:
        for b, p in zip(boards, payloads, strict=True):
            encode_frame(pc, b.address, 7, p)

    def decode_cycle() -> None:
        decoder.feed(stream)

    def decode_cycle_by_frame() -> None:
        for frame in frames:
            decoder.feed(frame)

    def roundtrip_cycle() -> None:
        for b, p in zip(boards, payloads, strict=True):
            decoder.feed(encode_frame(pc, b.address, 7, p))

    print(f"python {platform.python_version()} on {platform.machine()}, {n} boards per cycle")
    print(f"telemetry payload {len(payloads[0])} B, encoded frame {len(frames[0])} B (mean {len(stream) / n:.1f} B)")
    print("\nframing (frames/s; target >= 200k for encode+decode)")
    results = {
        "encode_frame": rate(encode_cycle, n, seconds),
        "decode, whole cycle per feed": rate(decode_cycle, n, seconds),
        "decode, one frame per feed": rate(decode_cycle_by_frame, n, seconds),
        "encode + decode (frame per feed)": rate(roundtrip_cycle, n, seconds),
    }
    for name, value in results.items():
        print(f"  {name:<34} {value / 1e3:8.0f} k/s   {1e6 / value:6.2f} us/frame")
    verdict = "meets" if results["encode + decode (frame per feed)"] >= TARGET_FRAMES_PER_S else "MISSES"
    print(f"  -> encode + decode {verdict} the {TARGET_FRAMES_PER_S // 1000}k frames/s target")

    body = frames[0][1:-1]
    print("\nFCS-16 over one 46-byte header+payload+FCS")
    for name, fn in (("fcs16 (crc_hqx on reversed bits)", fcs16), ("fcs16_reference (table loop)", fcs16_reference)):
        value = rate(lambda fn=fn: fn(body), 1, seconds / 2)
        print(f"  {name:<34} {1e6 / value:6.2f} us")

    scaling = boards[0].scaling
    command = Command(CommandMode.POSITION_FF, 0.3, 0.01, 10.0, 12345)
    command_payload = encode_command(command, scaling)
    table = board_map.scaling_table()
    modes = [CommandMode.POSITION_FF] * n
    setpoints = [0.3 if b.kind == "linear" else 0.1 for b in boards]
    zeros = [0.0] * n
    frames_writer = CommandFrames(FrameEncoder(pc), [b.address for b in boards], table)
    arrays = decode_telemetry_many(payloads, table)
    setpoint_array, zero_array = np.asarray(setpoints), np.zeros(n)
    print("\npayloads, the 1 kHz paths (us per actuator)")
    costs = {
        f"CommandFrames.frames (driver, {n} framed)": rate(
            lambda: frames_writer.frames(CommandMode.POSITION_FF, 1, setpoint_array, zero_array, zero_array), n, seconds
        ),
        f"encode_telemetry_many (sim, batch of {n})": rate(lambda: encode_telemetry_many(arrays, table), n, seconds),
        "decode_command (sim, per frame)": rate(lambda: decode_command(command_payload, scaling), 1, seconds),
        f"encode_commands (batch of {n})": rate(
            lambda: encode_commands(modes, setpoints, zeros, zeros, sequence=1, table=table), n, seconds
        ),
        f"decode_telemetry_many (batch of {n})": rate(lambda: decode_telemetry_many(payloads, table), n, seconds),
    }
    for name, value in costs.items():
        print(f"  {name:<42} {1e6 / value:6.2f} us")
    print("\npayloads, one board (a batch of one: tests and tools, us per call)")
    single = {
        "encode_command": rate(lambda: encode_command(command, scaling), 1, seconds),
        "encode_telemetry": rate(lambda: encode_telemetry(telemetry[0], scaling), 1, seconds),
        "decode_telemetry": rate(lambda: decode_telemetry(payloads[0], boards[0].scaling), 1, seconds),
    }
    for name, value in single.items():
        print(f"  {name:<42} {1e6 / value:6.2f} us")


if __name__ == "__main__":
    main()
