"""The project's NDLCom payloads: actuator commands and telemetry as versioned, little-endian, fixed layouts.

Physical values travel as int32 fixed point with a per-board LSB from the board map (e.g. 1 um or 1 urad per LSB),
so NaN and infinity have no encoding at all, and the encoders refuse values outside the board's wire range instead
of clamping. Byte 0 is the payload type, byte 1 the layout version; docs/protocol.md has the byte tables.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Sequence
from enum import IntEnum, IntFlag
from typing import Final, NamedTuple

import numpy as np

from rh5_bringup.hardware.ndlcom.errors import PayloadError
from rh5_bringup.hardware.ndlcom.scaling import INT16_MAX, INT16_MIN, INT32_MAX, INT32_MIN, Scaling, ScalingTable

__all__ = [
    "COMMAND_LAYOUT",
    "COMMAND_VERSION",
    "CURRENT_LSB",
    "MAX_MODE",
    "TELEMETRY_LAYOUT",
    "TELEMETRY_VERSION",
    "TEMPERATURE_LSB",
    "Command",
    "CommandMode",
    "ErrorFlags",
    "PayloadError",
    "PayloadType",
    "StatusFlags",
    "Telemetry",
    "TelemetryArrays",
    "decode_command",
    "decode_telemetry",
    "decode_telemetry_many",
    "decode_telemetry_of",
    "encode_command",
    "encode_commands",
    "encode_telemetry",
    "encode_telemetry_many",
    "payload_type",
]

COMMAND_VERSION: Final = 1
TELEMETRY_VERSION: Final = 1
CURRENT_LSB: Final = 1e-3
"""Motor current, A per LSB (1 mA), the same on every board."""
TEMPERATURE_LSB: Final = 1e-2
"""Temperature, deg C per LSB (0.01 deg C, int16: -327.68 .. 327.67 deg C)."""

COMMAND_LAYOUT: Final = struct.Struct("<4BI3i")
"""type, version, mode, reserved, sequence, setpoint, velocity_ff, effort_ff: 20 bytes."""
TELEMETRY_LAYOUT: Final = struct.Struct("<4B2HIQ4ihH")
"""type, version, mode, reserved, status, errors, sequence, board_time_us, position, velocity, effort, current,
temperature, reserved: 40 bytes."""


class PayloadType(IntEnum):
    """Byte 0 of every payload."""

    COMMAND = 0x01
    TELEMETRY = 0x02


class CommandMode(IntEnum):
    """What a board does with a command (byte 2). 0 is OFF, so a zeroed payload body never drives a motor."""

    OFF = 0
    """Power stage off; setpoint and feed-forwards must be 0."""
    HOLD = 1
    """Hold the position the board latched when entering HOLD; setpoint and feed-forwards must be 0."""
    POSITION = 2
    """Track ``setpoint`` with the board's position loop; feed-forwards must be 0."""
    POSITION_FF = 3
    """Track ``setpoint`` and add the velocity and effort feed-forwards to the board's cascade."""


_COMMAND_FIELDS: Final = ("setpoint", "velocity_ff", "effort_ff")
_USED_FIELDS: Final = {  # (setpoint, velocity_ff, effort_ff) each mode takes; the others must be exactly 0
    CommandMode.OFF: (False, False, False),
    CommandMode.HOLD: (False, False, False),
    CommandMode.POSITION: (True, False, False),
    CommandMode.POSITION_FF: (True, True, True),
}


class StatusFlags(IntFlag):
    """Telemetry status bits (uint16): what the board is doing."""

    NONE = 0
    ENABLED = 1 << 0
    """Power stage on."""
    HOLDING = 1 << 1
    """Holding a latched position (HOLD mode, or on its own after COMMAND_TIMEOUT)."""
    AT_LIMIT = 1 << 2
    """At one of the board's own soft position limits."""
    CALIBRATED = 1 << 3
    """Incremental encoder offset initialised from the absolute sensor."""
    SATURATED = 1 << 4
    """Current loop at its limit: the setpoint is not being tracked with full authority."""
    FEED_FORWARD = 1 << 5
    """Feed-forwards applied (POSITION_FF accepted)."""


class ErrorFlags(IntFlag):
    """Telemetry error bits (uint16): why the board refuses to drive or has stopped."""

    NONE = 0
    OVERTEMP = 1 << 0
    OVERCURRENT = 1 << 1
    COMMAND_TIMEOUT = 1 << 2
    """No valid command within the board's timeout: it holds."""
    ENCODER_FAULT = 1 << 3
    UNDERVOLTAGE = 1 << 4
    OVERVOLTAGE = 1 << 5
    FOLLOWING_ERROR = 1 << 6
    """Position error beyond the board's bound."""
    BAD_COMMAND = 1 << 7
    """The last command payload was refused (type, version, length, mode or range)."""


# --------------------------------------------------------------------------------------------------- records


class Command(NamedTuple):
    """A command to one actuator, in SI units (linear: m, m/s, N; rotary: rad, rad/s, Nm)."""

    mode: CommandMode
    setpoint: float = 0.0
    velocity_ff: float = 0.0
    effort_ff: float = 0.0
    """Force or torque feed-forward; the board turns it into motor current with its own motor constant."""
    sequence: int = 0
    """uint32, echoed in telemetry; the driver's cycle number."""


class Telemetry(NamedTuple):
    """What one board reports each cycle, in SI units (and deg C)."""

    mode: CommandMode
    """The mode the board is actually in (it may differ from the command, e.g. HOLD after a timeout)."""
    status: StatusFlags
    errors: ErrorFlags
    sequence: int
    """The sequence number of the last command the board accepted."""
    board_time_us: int
    """Board clock, microseconds (uint64)."""
    position: float
    velocity: float
    effort: float
    current: float
    """Motor current, A."""
    temperature: float
    """Motor driver temperature, deg C."""


# --------------------------------------------------------------------------------------------------- layouts

COMMAND_DTYPE: Final = np.dtype(
    [("type", "u1"), ("version", "u1"), ("mode", "u1"), ("reserved", "u1"), ("sequence", "<u4")]
    + [(name, "<i4") for name in _COMMAND_FIELDS]
)
TELEMETRY_DTYPE: Final = np.dtype(
    [("type", "u1"), ("version", "u1"), ("mode", "u1"), ("reserved", "u1"), ("status", "<u2"), ("errors", "<u2")]
    + [("sequence", "<u4"), ("board_time_us", "<u8")]
    + [(name, "<i4") for name in ("position", "velocity", "effort", "current")]
    + [("temperature", "<i2"), ("reserved2", "<u2")]
)
assert COMMAND_DTYPE.itemsize == COMMAND_LAYOUT.size
assert TELEMETRY_DTYPE.itemsize == TELEMETRY_LAYOUT.size

MAX_MODE: Final = int(max(CommandMode))
"""The highest mode a board may report: telemetry naming another is invalid (a plain int: numpy compares an IntEnum
member through Python objects, ~5 us a comparison)."""
_USED_MASK: Final = np.array([_USED_FIELDS[m] for m in CommandMode], dtype=bool)  # (mode, field)
_MEASURED: Final = ("position", "velocity", "effort", "current", "temperature")
_MEASURED_BOUNDS: Final = np.array([[INT32_MIN, INT32_MAX]] * 4 + [[INT16_MIN, INT16_MAX]], dtype=float)
_COUNTERS: Final = (("status", 0xFFFF), ("errors", 0xFFFF), ("sequence", 0xFFFFFFFF), ("board_time_us", 2**64 - 1))


# --------------------------------------------------------------------------------------------------- checks


def payload_type(data: bytes) -> PayloadType:
    """The type byte of ``data`` (for dispatching), refusing unknown types."""
    if len(data) < 2:
        raise PayloadError(f"payload of {len(data)} bytes is too short for its type and version bytes")
    try:
        return PayloadType(data[0])
    except ValueError:
        raise PayloadError(f"unknown payload type 0x{data[0]:02x}") from None


def _check_header(data: bytes, kind: PayloadType, version: int, layout: struct.Struct) -> None:
    if len(data) < 2:
        raise PayloadError(f"payload of {len(data)} bytes is too short for its type and version bytes")
    if data[0] != kind:
        raise PayloadError(f"payload type is 0x{data[0]:02x}, expected 0x{kind:02x} ({kind.name})")
    if data[1] != version:
        raise PayloadError(f"{kind.name} layout version {data[1]} is not supported (this decoder reads {version})")
    if len(data) != layout.size:
        raise PayloadError(f"{kind.name} v{version} payload must be {layout.size} bytes, got {len(data)}")


def _mode(raw: int) -> CommandMode:
    try:
        return CommandMode(raw)
    except ValueError:
        raise PayloadError(f"unknown command mode {raw}") from None


def _board(table: ScalingTable, index: int) -> str:
    """The prefix naming board ``index`` in an error message ("" for an unnamed single board)."""
    name = table.names[index]
    return f"{name}: " if name else ""


def _modes(modes: Sequence[int] | np.ndarray, table: ScalingTable) -> np.ndarray:
    """``modes`` as an integer array of one CommandMode per board, or PayloadError."""
    n = len(table)
    array = np.asarray(modes)
    if array.shape != (n,) or array.dtype.kind not in "iu":
        raise PayloadError(f"modes must be {n} CommandMode values, got {modes!r}")
    if n and (array.max() > MAX_MODE or (array.dtype.kind == "i" and array.min() < 0)):  # two reductions: 1 kHz
        i = int(np.argmax((array < 0) | (array > MAX_MODE)))
        raise PayloadError(f"{_board(table, i)}unknown command mode {int(array[i])}")
    return array


@functools.lru_cache(maxsize=128)
def _single(scaling: Scaling) -> ScalingTable:
    """The table of one unnamed board (kept per scaling): the scalar codecs are the batch codecs on one board."""
    return ScalingTable([scaling], ("",))


# --------------------------------------------------------------------------------------------------- command


def encode_commands(
    modes: Sequence[int] | np.ndarray,
    setpoint: Sequence[float] | np.ndarray,
    velocity_ff: Sequence[float] | np.ndarray,
    effort_ff: Sequence[float] | np.ndarray,
    *,
    sequence: int,
    table: ScalingTable,
) -> list[bytes]:
    """COMMAND v1 payloads for n boards at once (one per board, in table order).

    :raises PayloadError: naming the first offending board: a non-finite value or one outside the board's wire
        range, a nonzero field the mode does not use, an unknown mode, a sequence outside uint32.
    """
    n = len(table)
    mode_array = _modes(modes, table)
    values = np.array([setpoint, velocity_ff, effort_ff], dtype=float)
    if values.shape != (3, n):
        raise PayloadError(f"setpoint, velocity_ff and effort_ff must have {n} values each")
    if not 0 <= sequence <= 0xFFFFFFFF:
        raise PayloadError(f"sequence {sequence!r} is outside uint32")
    used = _USED_MASK[mode_array.astype(np.intp)].T
    finite = np.isfinite(values)
    ok = np.where(used, finite & (values >= table.low) & (values <= table.high), values == 0.0)
    if not ok.all():
        row, col = np.argwhere(~ok)[0]
        value, name, where = float(values[row, col]), _COMMAND_FIELDS[row], _board(table, col)
        if not used[row, col]:
            mode = CommandMode(int(mode_array[col])).name
            raise PayloadError(f"{where}{name} must be 0 in {mode} mode, got {value!r}")
        if not finite[row, col]:
            raise PayloadError(f"{where}{name} is {value!r}: only finite values can be encoded")
        low, high = float(table.low[row, col]), float(table.high[row, col])
        raise PayloadError(f"{where}{name} = {value!r} is outside the wire range [{low}, {high}]")
    raw = np.rint(np.where(used, values, 0.0) / table.lsb).astype(np.int32)
    out = np.zeros(n, dtype=COMMAND_DTYPE)
    out["type"], out["version"] = int(PayloadType.COMMAND), COMMAND_VERSION
    out["mode"], out["sequence"] = mode_array, sequence
    out["setpoint"], out["velocity_ff"], out["effort_ff"] = raw
    blob, size = out.tobytes(), COMMAND_LAYOUT.size
    return [blob[i : i + size] for i in range(0, n * size, size)]


def encode_command(command: Command, scaling: Scaling) -> bytes:
    """The COMMAND v1 payload of one ``command`` for a board with ``scaling``: ``encode_commands`` on one board."""
    mode, setpoint, velocity_ff, effort_ff, sequence = command
    if not isinstance(mode, int):
        raise PayloadError(f"unknown command mode {mode!r}")
    return encode_commands([mode], [setpoint], [velocity_ff], [effort_ff], sequence=sequence, table=_single(scaling))[0]


def _require_zero(value: float, name: str, mode: CommandMode) -> None:
    if value != 0:
        raise PayloadError(f"{name} must be 0 in {mode.name} mode, got {value!r}")


def decode_command(data: bytes, scaling: Scaling) -> Command:
    """The command in a COMMAND v1 payload, with the checks of ``encode_commands`` (the board's side)."""
    _check_header(data, PayloadType.COMMAND, COMMAND_VERSION, COMMAND_LAYOUT)
    _, _, raw_mode, reserved, sequence, setpoint, velocity_ff, effort_ff = COMMAND_LAYOUT.unpack(data)
    mode = _mode(raw_mode)
    if reserved:
        raise PayloadError(f"reserved byte 3 of COMMAND is 0x{reserved:02x}, must be 0")
    if mode == CommandMode.POSITION_FF:
        return Command(
            mode,
            scaling.position.check_raw(setpoint, "setpoint"),
            scaling.velocity.check_raw(velocity_ff, "velocity_ff"),
            scaling.effort.check_raw(effort_ff, "effort_ff"),
            sequence,
        )
    _require_zero(velocity_ff, "velocity_ff", mode)
    _require_zero(effort_ff, "effort_ff", mode)
    if mode == CommandMode.POSITION:
        return Command(mode, scaling.position.check_raw(setpoint, "setpoint"), 0.0, 0.0, sequence)
    _require_zero(setpoint, "setpoint", mode)
    return Command(mode, 0.0, 0.0, 0.0, sequence)


# --------------------------------------------------------------------------------------------------- telemetry


class TelemetryArrays(NamedTuple):
    """Telemetry of n boards as arrays in table order (SI units; flags as integer arrays)."""

    mode: np.ndarray
    status: np.ndarray
    errors: np.ndarray
    sequence: np.ndarray
    board_time_us: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    current: np.ndarray
    temperature: np.ndarray


def encode_telemetry_many(telemetry: TelemetryArrays, table: ScalingTable) -> list[bytes]:
    """TELEMETRY v1 payloads for n boards at once (the boards' side: the simulated hardware).

    Measured values are not limited to the command range, only to what their field can hold.
    :raises PayloadError: naming the first offending board: a non-finite value or one its field cannot hold, an
        unknown mode, flags beyond uint16, a sequence beyond uint32, a board time beyond uint64.
    """
    n = len(table)
    mode = _modes(telemetry.mode, table)
    counters = []
    for name, top in _COUNTERS:
        value = np.asarray(getattr(telemetry, name))
        in_range = value.dtype == TELEMETRY_DTYPE[name] or not n or (value.min() >= 0 and value.max() <= top)
        if value.shape != (n,) or value.dtype.kind not in "iu" or not in_range:
            raise PayloadError(
                f"telemetry integer field out of range (status/errors uint16, sequence uint32, board_time_us uint64): "
                f"{name}={value.tolist()!r}"
            )
        counters.append(value)
    values = np.array([getattr(telemetry, name) for name in _MEASURED], dtype=float)
    if values.shape != (5, n):
        raise PayloadError(f"telemetry must have {n} values per field")
    lsb = np.vstack([table.lsb, np.full((1, n), CURRENT_LSB), np.full((1, n), TEMPERATURE_LSB)])
    raw = np.rint(values / lsb)
    finite = np.isfinite(raw)
    ok = finite & (raw >= _MEASURED_BOUNDS[:, :1]) & (raw <= _MEASURED_BOUNDS[:, 1:])
    if not ok.all():
        row, col = np.argwhere(~ok)[0]
        value, name, where = float(values[row, col]), _MEASURED[row], _board(table, col)
        if not finite[row, col]:
            raise PayloadError(f"{where}{name} is {value!r}: only finite values can be encoded")
        low, high = _MEASURED_BOUNDS[row] * lsb[row, col]
        raise PayloadError(f"{where}{name} = {value!r} does not fit the wire field ({low:.6g} .. {high:.6g})")
    out = np.zeros(n, dtype=TELEMETRY_DTYPE)
    out["type"], out["version"], out["mode"] = int(PayloadType.TELEMETRY), TELEMETRY_VERSION, mode
    out["status"], out["errors"], out["sequence"], out["board_time_us"] = counters
    out["position"], out["velocity"], out["effort"], out["current"] = raw[:4].astype(np.int32)
    out["temperature"] = raw[4].astype(np.int16)
    blob, size = out.tobytes(), TELEMETRY_LAYOUT.size
    return [blob[i : i + size] for i in range(0, n * size, size)]


def encode_telemetry(telemetry: Telemetry, scaling: Scaling) -> bytes:
    """The TELEMETRY v1 payload of one board: ``encode_telemetry_many`` on one board."""
    if not isinstance(telemetry.mode, int):
        raise PayloadError(f"unknown command mode {telemetry.mode!r}")
    return encode_telemetry_many(TelemetryArrays(*([value] for value in telemetry)), _single(scaling))[0]


def decode_telemetry_of(
    payloads: Sequence[bytes] | bytes, boards: np.ndarray | slice, table: ScalingTable
) -> tuple[np.ndarray, TelemetryArrays]:
    """Decode TELEMETRY v1 payloads (a list, or already joined) of the boards at ``boards`` (table indices, any
    subset, or a slice) in one pass; the numpy form of the driver's C decoder (``_framing.decode_telemetry_into``).

    The payloads must have the size, type and version bytes of TELEMETRY v1 (checked per frame by the caller,
    cheaply); returns which of them also have a known mode and zero reserved fields (the rest are to be dropped)
    and the arrays of all of them, in SI units.
    """
    rec = np.frombuffer(payloads if isinstance(payloads, bytes) else b"".join(payloads), dtype=TELEMETRY_DTYPE)
    valid = (rec["mode"] <= MAX_MODE) & (rec["reserved"] == 0) & (rec["reserved2"] == 0)
    lsb = table.lsb[:, boards]
    return valid, TelemetryArrays(
        rec["mode"],
        rec["status"],
        rec["errors"],
        rec["sequence"],
        rec["board_time_us"],
        rec["position"] * lsb[0],
        rec["velocity"] * lsb[1],
        rec["effort"] * lsb[2],
        rec["current"] * CURRENT_LSB,
        rec["temperature"] * TEMPERATURE_LSB,
    )


def decode_telemetry_many(payloads: Sequence[bytes], table: ScalingTable) -> TelemetryArrays:
    """One TELEMETRY v1 payload per board (in table order), every check applied, naming the first bad board."""
    if len(payloads) != len(table):
        raise PayloadError(f"{len(payloads)} payloads for {len(table)} boards")
    size = TELEMETRY_LAYOUT.size
    for index, data in enumerate(payloads):
        if len(data) != size or data[0] != PayloadType.TELEMETRY or data[1] != TELEMETRY_VERSION:
            try:
                _check_header(data, PayloadType.TELEMETRY, TELEMETRY_VERSION, TELEMETRY_LAYOUT)
            except PayloadError as error:
                raise PayloadError(f"{_board(table, index)}{error}") from None
    valid, arrays = decode_telemetry_of(payloads, slice(None), table)
    if not valid.all():
        i = int(np.argmin(valid))
        mode, reserved = int(arrays.mode[i]), payloads[i][3] | int.from_bytes(payloads[i][38:40], "little")
        reason = f"unknown command mode {mode}" if mode > MAX_MODE else f"reserved fields are {reserved}, must be 0"
        raise PayloadError(f"{_board(table, i)}{reason}")
    return arrays


def decode_telemetry(data: bytes, scaling: Scaling) -> Telemetry:
    """The telemetry in one TELEMETRY v1 payload: ``decode_telemetry_many`` on one board. Unknown flag bits are
    kept (IntFlag), unknown modes refused."""
    a = decode_telemetry_many([data], _single(scaling))
    return Telemetry(
        CommandMode(int(a.mode[0])),
        StatusFlags(int(a.status[0])),
        ErrorFlags(int(a.errors[0])),
        int(a.sequence[0]),
        int(a.board_time_us[0]),
        *(float(getattr(a, name)[0]) for name in _MEASURED),
    )
