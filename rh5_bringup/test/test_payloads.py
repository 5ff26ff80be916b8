"""COMMAND and TELEMETRY payloads: pinned bytes, round trips, header checks, refused values, flags, batch codecs."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.payloads import (
    COMMAND_LAYOUT,
    TELEMETRY_LAYOUT,
    Command,
    CommandMode,
    ErrorFlags,
    PayloadError,
    PayloadType,
    StatusFlags,
    Telemetry,
    decode_command,
    decode_telemetry,
    decode_telemetry_many,
    encode_command,
    encode_commands,
    encode_telemetry,
    payload_type,
)
from rh5_bringup.hardware.ndlcom.scaling import Quantity, Scaling, ScalingTable

LINEAR = Scaling(Quantity(1e-6, 0.15, 0.50), Quantity(1e-6, -1.0, 1.0), Quantity(1e-3, -10000.0, 10000.0))
ROTARY = Scaling(Quantity(1e-6, -6.3, 6.3), Quantity(1e-6, -40.0, 40.0), Quantity(1e-3, -500.0, 500.0))
TELEMETRY = Telemetry(
    CommandMode.POSITION_FF,
    StatusFlags.ENABLED | StatusFlags.CALIBRATED,
    ErrorFlags.NONE,
    sequence=0xDEADBEEF,
    board_time_us=2**40 + 5,
    position=0.273,
    velocity=-0.0125,
    effort=-4123.456,
    current=12.345,
    temperature=41.25,
)


def close(a: float, b: float, lsb: float) -> bool:
    return abs(a - b) <= lsb / 2 * (1 + 1e-9) + 1e-15


# --------------------------------------------------------------------------------------------------- pinned bytes


def test_command_bytes_are_the_documented_layout() -> None:
    payload = encode_command(Command(CommandMode.POSITION_FF, 0.273, -0.0125, 12.5, 0x01020304), LINEAR)
    expected = bytes.fromhex("01 01 03 00 04030201") + struct.pack("<3i", 273_000, -12_500, 12_500)
    assert payload == expected
    assert len(payload) == COMMAND_LAYOUT.size == 20


def test_telemetry_bytes_are_the_documented_layout() -> None:
    payload = encode_telemetry(TELEMETRY, LINEAR)
    expected = (
        bytes([0x02, 0x01, 0x03, 0x00])
        + struct.pack("<HH", 0b1001, 0)
        + bytes.fromhex("efbeadde")
        + (2**40 + 5).to_bytes(8, "little")
        + struct.pack("<4i", 273_000, -12_500, -4_123_456, 12_345)
        + struct.pack("<hH", 4125, 0)
    )
    assert payload == expected
    assert len(payload) == TELEMETRY_LAYOUT.size == 40


# --------------------------------------------------------------------------------------------------- round trips


@given(
    st.floats(0.15, 0.50), st.floats(-1.0, 1.0), st.floats(-10000.0, 10000.0), st.integers(0, 2**32 - 1), st.booleans()
)
def test_commands_round_trip_within_half_an_lsb(
    setpoint: float, velocity: float, effort: float, sequence: int, feed_forward: bool
) -> None:
    if feed_forward:
        command = Command(CommandMode.POSITION_FF, setpoint, velocity, effort, sequence)
    else:
        command = Command(CommandMode.POSITION, setpoint, sequence=sequence)
    decoded = decode_command(encode_command(command, LINEAR), LINEAR)
    assert decoded.mode is command.mode
    assert decoded.sequence == sequence
    for got, sent, quantity in zip(decoded[1:4], command[1:4], LINEAR, strict=True):
        assert close(got, sent, quantity.lsb)


@pytest.mark.parametrize("mode", [CommandMode.OFF, CommandMode.HOLD])
def test_off_and_hold_round_trip(mode: CommandMode) -> None:
    payload = encode_command(Command(mode, sequence=7), ROTARY)
    assert payload[2] == mode
    assert payload[8:] == bytes(12)
    assert decode_command(payload, ROTARY) == Command(mode, 0.0, 0.0, 0.0, 7)


def test_telemetry_round_trips_with_flags() -> None:
    decoded = decode_telemetry(encode_telemetry(TELEMETRY, LINEAR), LINEAR)
    assert decoded.mode is CommandMode.POSITION_FF
    assert decoded.status == StatusFlags.ENABLED | StatusFlags.CALIBRATED
    assert StatusFlags.HOLDING not in decoded.status
    assert isinstance(decoded.errors, ErrorFlags)
    assert decoded[3:5] == TELEMETRY[3:5]
    for got, sent in zip(decoded[5:], TELEMETRY[5:], strict=True):
        assert got == pytest.approx(sent, abs=1e-5)


def test_every_error_flag_round_trips_and_unknown_bits_are_kept() -> None:
    for flag in ErrorFlags:
        t = TELEMETRY._replace(errors=flag, status=StatusFlags.HOLDING | StatusFlags.AT_LIMIT)
        assert decode_telemetry(encode_telemetry(t, ROTARY), ROTARY).errors == flag
    t = TELEMETRY._replace(errors=ErrorFlags(0x8000 | ErrorFlags.OVERTEMP), status=StatusFlags(0x4000))
    decoded = decode_telemetry(encode_telemetry(t, ROTARY), ROTARY)
    assert decoded.errors == 0x8001
    assert ErrorFlags.OVERTEMP in decoded.errors
    assert decoded.status == 0x4000


@given(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0, 1, 2]))
def test_nan_never_reaches_the_wire(value: float, field: int) -> None:
    """Whatever float is offered, the encoder either refuses it or emits a value inside the wire range."""
    values = [0.3, 0.0, 0.0]
    values[field] = value
    try:
        payload = encode_command(Command(CommandMode.POSITION_FF, *values), LINEAR)
    except PayloadError:
        assert not LINEAR[field].low <= value <= LINEAR[field].high
        return
    decoded = decode_command(payload, LINEAR)
    assert all(math.isfinite(v) for v in decoded[1:4])
    assert LINEAR[field].low - 1e-6 <= decoded[1 + field] <= LINEAR[field].high + 1e-6


# --------------------------------------------------------------------------------------------------- refused values


@pytest.mark.parametrize(
    ("command", "match"),
    [
        (Command(CommandMode.POSITION, math.nan), "setpoint is nan: only finite"),
        (Command(CommandMode.POSITION_FF, 0.3, math.inf, 0.0), "velocity_ff is inf: only finite"),
        (Command(CommandMode.POSITION_FF, 0.3, 0.0, -math.inf), "effort_ff is -inf: only finite"),
        (Command(CommandMode.POSITION, 273.0), r"setpoint = 273.0 is outside the wire range \[0.15, 0.5\]"),
        (Command(CommandMode.POSITION, 0.0), "outside the wire range"),
        (Command(CommandMode.POSITION_FF, 0.3, 1.5, 0.0), "velocity_ff = 1.5 is outside"),
        (Command(CommandMode.POSITION_FF, 0.3, 0.0, 2e4), "effort_ff = 20000.0 is outside"),
        (Command(CommandMode.HOLD, 0.3), "setpoint must be 0 in HOLD mode"),
        (Command(CommandMode.OFF, 0.0, math.nan), "velocity_ff must be 0 in OFF mode"),
        (Command(CommandMode.POSITION, 0.3, 0.0, 1.0), "effort_ff must be 0 in POSITION mode"),
        (Command(CommandMode.POSITION, 0.3, sequence=2**32), "sequence 4294967296"),
        (Command(CommandMode.POSITION, 0.3, sequence=-1), "sequence -1"),
        (Command(7, 0.3), "unknown command mode 7"),  # type: ignore[arg-type]
    ],
)
def test_encoder_refuses_unsafe_commands(command: Command, match: str) -> None:
    with pytest.raises(PayloadError, match=match):
        encode_command(command, LINEAR)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"position": math.nan}, "position is nan"),
        ({"velocity": math.inf}, "velocity is inf"),
        ({"current": 3e6}, "current = 3000000.0 does not fit"),
        ({"temperature": 400.0}, "temperature = 400.0 does not fit"),
        ({"status": 0x10000}, "status/errors uint16"),
        ({"board_time_us": -1}, "board_time_us uint64"),
        ({"mode": 9}, "unknown command mode 9"),
    ],
)
def test_telemetry_encoder_refuses_what_the_fields_cannot_hold(change: dict[str, object], match: str) -> None:
    with pytest.raises(PayloadError, match=match):
        encode_telemetry(TELEMETRY._replace(**change), LINEAR)


def test_telemetry_may_report_measurements_outside_the_command_range() -> None:
    t = TELEMETRY._replace(position=0.6, velocity=-3.0)  # beyond LINEAR's wire ranges, measured, not commanded
    assert decode_telemetry(encode_telemetry(t, LINEAR), LINEAR).position == pytest.approx(0.6)


# --------------------------------------------------------------------------------------------------- decode checks


GOOD_COMMAND = encode_command(Command(CommandMode.POSITION, 0.3, sequence=1), LINEAR)
GOOD_TELEMETRY = encode_telemetry(TELEMETRY, LINEAR)


@pytest.mark.parametrize(
    ("payload", "match"),
    [
        (b"", "payload of 0 bytes is too short"),
        (b"\x01", "payload of 1 bytes is too short"),
        (GOOD_TELEMETRY, "payload type is 0x02, expected 0x01 .COMMAND."),
        (b"\x01\x02" + GOOD_COMMAND[2:], "COMMAND layout version 2 is not supported"),
        (GOOD_COMMAND + b"\x00", "COMMAND v1 payload must be 20 bytes, got 21"),
        (GOOD_COMMAND[:-1], "COMMAND v1 payload must be 20 bytes, got 19"),
        (GOOD_COMMAND[:2] + b"\x04" + GOOD_COMMAND[3:], "unknown command mode 4"),
        (GOOD_COMMAND[:3] + b"\x01" + GOOD_COMMAND[4:], "reserved byte 3"),
        (GOOD_COMMAND[:12] + b"\x01" + GOOD_COMMAND[13:], "velocity_ff must be 0 in POSITION mode"),
        (GOOD_COMMAND[:8] + struct.pack("<i", 10**9) + GOOD_COMMAND[12:], "setpoint = 1000.0 is outside"),
    ],
)
def test_command_decoder_checks_each_field_with_its_own_message(payload: bytes, match: str) -> None:
    with pytest.raises(PayloadError, match=match):
        decode_command(payload, LINEAR)


@pytest.mark.parametrize(
    ("payload", "match"),
    [
        (GOOD_COMMAND, "payload type is 0x01, expected 0x02 .TELEMETRY."),
        (b"\x02\x00" + GOOD_TELEMETRY[2:], "TELEMETRY layout version 0 is not supported"),
        (GOOD_TELEMETRY[:39], "TELEMETRY v1 payload must be 40 bytes, got 39"),
        (GOOD_TELEMETRY[:2] + b"\xff" + GOOD_TELEMETRY[3:], "unknown command mode 255"),
        (GOOD_TELEMETRY[:38] + b"\x00\x01", "reserved fields"),
    ],
)
def test_telemetry_decoder_checks_each_field_with_its_own_message(payload: bytes, match: str) -> None:
    with pytest.raises(PayloadError, match=match):
        decode_telemetry(payload, LINEAR)


def test_payload_type_dispatch() -> None:
    assert payload_type(GOOD_COMMAND) is PayloadType.COMMAND
    assert payload_type(GOOD_TELEMETRY) is PayloadType.TELEMETRY
    with pytest.raises(PayloadError, match="unknown payload type 0x09"):
        payload_type(b"\x09\x01")
    with pytest.raises(PayloadError, match="too short"):
        payload_type(b"\x01")


def test_payload_error_is_a_value_error() -> None:
    assert issubclass(PayloadError, ValueError)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((0.0, 0.0, 1.0), "lsb must be a positive finite"),
        ((math.nan, 0.0, 1.0), "lsb must be a positive finite"),
        ((1e-6, 1.0, 1.0), "low < high"),
        ((1e-6, 0.0, math.inf), "low < high"),
        ((1e-6, -1.0, 3000.0), "does not fit int32"),
    ],
)
def test_quantity_validates_its_scaling(args: tuple[float, float, float], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        Quantity(*args)


def test_full_quantity_spans_int32() -> None:
    q = Quantity.full(1e-3)
    assert (q.raw_low, q.raw_high) == (-(2**31), 2**31 - 1)


# --------------------------------------------------------------------------------------------------- batch codecs


def test_batch_command_encoder_names_the_offending_board() -> None:
    board_map = load_board_map()
    table = board_map.scaling_table()
    n = len(table)
    modes = np.full(n, CommandMode.POSITION)
    setpoint = np.array([0.3 if b.kind == "linear" else 0.0 for b in board_map])
    zeros = np.zeros(n)
    assert len(encode_commands(modes, setpoint, zeros, zeros, sequence=0, table=table)) == n
    bad = setpoint.copy()
    bad[23] = math.nan
    with pytest.raises(PayloadError, match="LLKnee_Act1: setpoint is nan: only finite values"):
        encode_commands(modes, bad, zeros, zeros, sequence=0, table=table)
    bad[23] = 0.6
    with pytest.raises(PayloadError, match=r"LLKnee_Act1: setpoint = 0.6 is outside the wire range \[0.15, 0.5\]"):
        encode_commands(modes, bad, zeros, zeros, sequence=0, table=table)
    ff = zeros.copy()
    ff[2] = 1.0
    with pytest.raises(PayloadError, match=r"BodyYaw: velocity_ff must be 0 in POSITION mode, got 1\.0"):
        encode_commands(modes, setpoint, ff, zeros, sequence=0, table=table)
    with pytest.raises(PayloadError, match="unknown command mode 4"):
        encode_commands(np.full(n, 4), setpoint, zeros, zeros, sequence=0, table=table)
    with pytest.raises(PayloadError, match="sequence"):
        encode_commands(modes, setpoint, zeros, zeros, sequence=2**32, table=table)


def test_batch_telemetry_decoder_reads_each_board_with_its_scaling_and_names_the_offending_one() -> None:
    table = ScalingTable([LINEAR, ROTARY, ROTARY], ["a", "b", "c"])
    telemetry = [TELEMETRY, TELEMETRY._replace(position=-1.5, errors=ErrorFlags.OVERTEMP), TELEMETRY]
    payloads = [encode_telemetry(t, s) for t, s in zip(telemetry, (LINEAR, ROTARY, ROTARY), strict=True)]
    arrays = decode_telemetry_many(payloads, table)
    for i, sent in enumerate(telemetry):
        for name in sent._fields:
            assert float(getattr(arrays, name)[i]) == pytest.approx(float(getattr(sent, name)), abs=1e-3), name
    with pytest.raises(PayloadError, match="b: TELEMETRY v1 payload must be 40 bytes, got 20"):
        decode_telemetry_many([payloads[0], payloads[1][:20], payloads[2]], table)
    with pytest.raises(PayloadError, match="c: unknown command mode 9"):
        decode_telemetry_many([*payloads[:2], payloads[2][:2] + b"\x09" + payloads[2][3:]], table)
    with pytest.raises(PayloadError, match="2 payloads for 3 boards"):
        decode_telemetry_many(payloads[:2], table)
