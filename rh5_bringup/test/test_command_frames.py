"""The driver's vectorised command frames are, byte for byte, what the frame-by-frame encoder sends."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.codec import FrameDecoder, FrameEncoder
from rh5_bringup.hardware.ndlcom.command_frames import CommandFrames
from rh5_bringup.hardware.ndlcom.payloads import CommandMode, decode_command, encode_commands

BOARD_MAP = load_board_map()
TABLE = BOARD_MAP.scaling_table()
ADDRESSES = BOARD_MAP.addresses()
N = len(ADDRESSES)


def _in_range(seed: int) -> np.ndarray:
    """(3, n) setpoint, velocity and effort values anywhere in the wire ranges, the ends included."""
    rng = np.random.default_rng(seed)
    values = rng.uniform(TABLE.low, TABLE.high)
    at_low, at_high = rng.integers(0, N, 3), rng.integers(0, N, 3)
    values[:, at_low] = TABLE.low[:, at_low]
    values[:, at_high] = TABLE.high[:, at_high]
    return values


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([CommandMode.POSITION_FF, CommandMode.HOLD]), st.integers(0, 2**32 - 1),
                          st.integers(0, 2**31)), min_size=1, max_size=6))  # fmt: skip
def test_frames_are_the_encoders_frames(cycles: list[tuple[CommandMode, int, int]]) -> None:
    """Several cycles in a row (frame counters carried on), POSITION_FF with values anywhere in the wire
    ranges and HOLD: the same bytes as encode_commands + FrameEncoder.encode, escapes included."""
    writer = CommandFrames(FrameEncoder(BOARD_MAP.pc_address), ADDRESSES, TABLE)
    reference = FrameEncoder(BOARD_MAP.pc_address)
    for mode, sequence, seed in cycles:
        values = _in_range(seed) if mode == CommandMode.POSITION_FF else np.zeros((3, N))
        assert mode != CommandMode.POSITION_FF or writer.fits(*values)
        expected = [
            reference.encode(address, payload)
            for address, payload in zip(
                ADDRESSES, encode_commands(np.full(N, int(mode)), *values, sequence=sequence, table=TABLE), strict=True
            )
        ]
        assert writer.frames(mode, sequence, *values) == expected


def test_counters_wrap_and_frames_decode_at_the_boards() -> None:
    writer = CommandFrames(FrameEncoder(BOARD_MAP.pc_address), ADDRESSES, TABLE)
    decoder = FrameDecoder()
    values = _in_range(1)
    for cycle in range(300):  # past the 8-bit frame counter's wrap
        frames = decoder.feed(b"".join(writer.frames(CommandMode.POSITION_FF, cycle, *values)))
        assert [f.counter for f in frames] == [cycle & 0xFF] * N
    assert decoder.stats().total().lost == 0
    for frame, board, value in zip(frames, BOARD_MAP, values.T, strict=True):
        command = decode_command(frame.payload, board.scaling)
        assert command.setpoint == pytest.approx(value[0], abs=board.scaling.position.lsb)


def test_only_values_in_the_wire_range_fit() -> None:
    writer = CommandFrames(FrameEncoder(BOARD_MAP.pc_address), ADDRESSES, TABLE)
    values = _in_range(2)
    assert writer.fits(*values)
    for bad in (np.nan, np.inf, TABLE.high[0, 0] + 1.0):
        broken = values.copy()
        broken[0, 0] = bad
        assert not writer.fits(*broken)
    with pytest.raises(ValueError, match="distinct receiver"):
        CommandFrames(FrameEncoder(1), [ADDRESSES[0]] * N, TABLE)
