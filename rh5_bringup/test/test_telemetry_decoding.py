"""The driver's telemetry decoding in C (``_framing.decode_telemetry_into``) against the numpy reference
(``payloads.decode_telemetry_of``): the same values at the same boards, invalid records dropped, and one round trip
per board and echoed command."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_bringup.hardware.ndlcom._framing import decode_telemetry_into
from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.payloads import (
    MAX_MODE,
    TEMPERATURE_LSB,
    CommandMode,
    TelemetryArrays,
    decode_telemetry_of,
    encode_telemetry_many,
)

BOARD_MAP = load_board_map()
TABLE = BOARD_MAP.scaling_table()
N = len(BOARD_MAP)
LSB = np.ascontiguousarray(TABLE.lsb, dtype=np.float64)


def _telemetry(rng: np.random.Generator) -> TelemetryArrays:
    """Random in-range telemetry of every board (table order)."""

    def ints(high: int) -> np.ndarray:
        return rng.integers(0, high, N)

    return TelemetryArrays(
        ints(int(MAX_MODE) + 1), ints(1 << 16), ints(1 << 16), ints(1 << 32), ints(1 << 40),
        rng.uniform(-0.05, 0.05, N), rng.uniform(-0.1, 0.1, N), rng.uniform(-500, 500, N),
        rng.uniform(-10, 10, N), rng.uniform(20, 80, N),
    )  # fmt: skip


class Arrays:
    """The driver's arrays that the decoding writes, filled with a marker to see what it left alone."""

    def __init__(self) -> None:
        self.out = [np.full(N, -7.0) for _ in range(4)] + [np.full(N, -7, dtype=np.int64) for _ in range(2)]
        self.heard_ns = np.full(N, -7, dtype=np.int64)
        self.heard_cycle = np.full(N, -7, dtype=np.int64)
        self.sent_ns = np.zeros(256, dtype=np.int64)
        self.echoed = np.full(N, -1, dtype=np.int64)
        self.latencies = np.zeros(N, dtype=np.int64)

    def decode(self, payloads: bytes, boards: bytes, now_ns: int, cycle: int) -> tuple[int, int, int]:
        return decode_telemetry_into(
            payloads, boards, LSB, *self.out, self.heard_ns, self.heard_cycle, self.sent_ns, self.echoed,
            self.latencies, now_ns, cycle, TEMPERATURE_LSB, int(MAX_MODE),
        )  # fmt: skip


def test_the_c_decoding_writes_what_the_numpy_reference_decodes_at_each_board() -> None:
    rng = np.random.default_rng(7)
    telemetry = _telemetry(rng)
    records = encode_telemetry_many(telemetry, TABLE)
    subset = rng.permutation(N)[: N - 5]  # five boards unheard this cycle, the rest in arrival order
    broken = {int(subset[0]): (2, 200), int(subset[1]): (3, 1), int(subset[2]): (38, 1)}  # mode, reserved fields
    payloads = bytearray(b"".join(records[b] for b in subset))
    for k, b in enumerate(subset):
        if int(b) in broken:
            offset, value = broken[int(b)]
            payloads[40 * k + offset] = value
    arrays = Arrays()
    invalid, board_time_us, echoes = arrays.decode(bytes(payloads), bytes(subset.astype(np.uint8)), 123, 45)

    valid, reference = decode_telemetry_of(bytes(payloads), subset.astype(np.intp), TABLE)
    assert invalid == int((~valid).sum()) == 3
    good = subset[valid]
    for written, expected in zip(
        arrays.out,
        (reference.position, reference.velocity, reference.effort, reference.temperature * 1.0,
         reference.status, reference.errors),
        strict=True,
    ):  # fmt: skip
        np.testing.assert_array_equal(written[good], expected[valid])
    left_alone = np.setdiff1d(np.arange(N), good)
    assert len(left_alone) == 8
    assert all((written[left_alone] == -7).all() for written in arrays.out)
    assert (arrays.heard_ns[good] == 123).all()
    assert (arrays.heard_ns[left_alone] == -7).all()
    assert (arrays.heard_cycle[good] == 45).all()
    assert board_time_us == int(reference.board_time_us[valid].max())
    assert echoes == 0  # nothing was sent yet
    np.testing.assert_allclose(arrays.out[0][good], telemetry.position[good], atol=TABLE.lsb[0][good].max())


def test_each_echoed_command_is_one_round_trip_per_board() -> None:
    rng = np.random.default_rng(8)
    telemetry = _telemetry(rng)._replace(sequence=np.full(N, 300), mode=np.full(N, int(CommandMode.HOLD)))
    payloads, boards = b"".join(encode_telemetry_many(telemetry, TABLE)), bytes(range(N))
    arrays = Arrays()
    arrays.sent_ns[300 % 256] = 1_000
    assert arrays.decode(payloads, boards, 4_000, 1)[2] == N
    np.testing.assert_array_equal(arrays.latencies, np.full(N, 3_000))
    assert (arrays.echoed == 300).all()
    assert arrays.decode(payloads, boards, 5_000, 2)[2] == 0  # the same command repeated: no new round trip


def test_buffers_of_the_wrong_size_are_refused() -> None:
    arrays = Arrays()
    payloads = b"".join(encode_telemetry_many(_telemetry(np.random.default_rng(9)), TABLE))
    with pytest.raises(ValueError, match="one 40-byte record per board"):
        arrays.decode(payloads[:-1], bytes(range(N)), 0, 0)
    arrays.out[0] = np.zeros(N - 1)
    with pytest.raises(ValueError, match="position"):
        arrays.decode(payloads, bytes(range(N)), 0, 0)
    arrays = Arrays()
    with pytest.raises(ValueError, match="board index"):
        arrays.decode(payloads[:40], bytes([N]), 0, 0)
