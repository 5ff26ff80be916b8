"""The project's NDLCom payloads: actuator commands and telemetry as versioned, little-endian, fixed layouts.

Physical values travel as int32 fixed point with a per-board LSB from the board map (e.g. 1 um or 1 urad per LSB),
so NaN and infinity have no encoding at all, and the encoders refuse values outside the board's wire range instead
of clamping. Byte 0 is the payload type, byte 1 the layout version; docs/protocol.md has the byte tables.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum, IntFlag
from typing import Final, NamedTuple

import numpy as np

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
    "Quantity",
    "Scaling",
    "ScalingTable",
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

INT32_MIN: Final = -(2**31)
INT32_MAX: Final = 2**31 - 1
INT16_MIN: Final = -(2**15)
INT16_MAX: Final = 2**15 - 1

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


class PayloadError(ValueError):
    """A payload cannot be encoded (non-finite or out-of-range value, inconsistent command) or decoded."""


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


@dataclass(frozen=True, slots=True)
class Quantity:
    """Fixed-point scaling of one physical quantity: ``value = raw * lsb``, commands limited to [low, high].

    [low, high] is the board's wire range: a coarse sanity bound that catches unit and sign-convention errors
    (mm for m, deg for rad), not a joint limit. Both ends must be representable in int32 at this LSB.
    """

    lsb: float
    low: float
    high: float
    raw_low: int = field(init=False, repr=False, compare=False)
    raw_high: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lsb) and self.lsb > 0.0):
            raise ValueError(f"lsb must be a positive finite number, got {self.lsb!r}")
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ValueError(f"range must be finite with low < high, got [{self.low!r}, {self.high!r}]")
        raw_low, raw_high = round(self.low / self.lsb), round(self.high / self.lsb)
        if raw_low < INT32_MIN or raw_high > INT32_MAX:
            raise ValueError(
                f"range [{self.low}, {self.high}] at lsb {self.lsb} does not fit int32 (+-{INT32_MAX * self.lsb:.6g})"
            )
        object.__setattr__(self, "raw_low", raw_low)
        object.__setattr__(self, "raw_high", raw_high)

    @classmethod
    def full(cls, lsb: float) -> Quantity:
        """The widest range int32 can carry at ``lsb``."""
        return cls(lsb, INT32_MIN * lsb, INT32_MAX * lsb)

    def to_wire(self, value: float, what: str) -> int:
        """``value`` in LSBs; refuses NaN, infinities and values outside [low, high]."""
        if self.low <= value <= self.high:
            return round(value / self.lsb)
        if not math.isfinite(value):
            raise PayloadError(f"{what} is {value!r}: only finite values can be encoded")
        raise PayloadError(f"{what} = {value!r} is outside the wire range [{self.low}, {self.high}]")

    def check_raw(self, raw: int, what: str) -> float:
        """A received ``raw`` value in SI units; refuses one outside [low, high]."""
        if self.raw_low <= raw <= self.raw_high:
            return raw * self.lsb
        raise PayloadError(f"{what} = {raw * self.lsb!r} is outside the wire range [{self.low}, {self.high}]")


class Scaling(NamedTuple):
    """One board's fixed-point scaling: position (m or rad), velocity (m/s or rad/s), effort (N or Nm)."""

    position: Quantity
    velocity: Quantity
    effort: Quantity


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


def _int(value: float, lsb: float, low: int, high: int, what: str) -> int:
    """``value`` in LSBs within [low, high] raw, for telemetry fields (which carry no board range)."""
    try:
        raw = round(value / lsb)
    except (ValueError, OverflowError):
        raise PayloadError(f"{what} is {value!r}: only finite values can be encoded") from None
    if low <= raw <= high:
        return raw
    raise PayloadError(f"{what} = {value!r} does not fit the wire field ({low * lsb:.6g} .. {high * lsb:.6g})")


# --------------------------------------------------------------------------------------------------- command


def _require_zero(value: float, name: str, mode: CommandMode) -> None:
    if value != 0:
        raise PayloadError(f"{name} must be 0 in {mode.name} mode, got {value!r}")


def encode_command(command: Command, scaling: Scaling) -> bytes:
    """The COMMAND v1 payload of ``command`` for a board with ``scaling``.

    :raises PayloadError: a non-finite or out-of-range value, a nonzero field the mode does not use, a sequence
        outside uint32, or an unknown mode.
    """
    mode, setpoint, velocity_ff, effort_ff, sequence = command
    if mode == CommandMode.POSITION_FF:
        raws = (
            scaling.position.to_wire(setpoint, "setpoint"),
            scaling.velocity.to_wire(velocity_ff, "velocity_ff"),
            scaling.effort.to_wire(effort_ff, "effort_ff"),
        )
    elif mode == CommandMode.POSITION:
        _require_zero(velocity_ff, "velocity_ff", mode)
        _require_zero(effort_ff, "effort_ff", mode)
        raws = (scaling.position.to_wire(setpoint, "setpoint"), 0, 0)
    elif mode in (CommandMode.OFF, CommandMode.HOLD):
        mode = CommandMode(mode)
        _require_zero(setpoint, "setpoint", mode)
        _require_zero(velocity_ff, "velocity_ff", mode)
        _require_zero(effort_ff, "effort_ff", mode)
        raws = (0, 0, 0)
    else:
        raise PayloadError(f"unknown command mode {mode!r}")
    try:
        return COMMAND_LAYOUT.pack(PayloadType.COMMAND, COMMAND_VERSION, mode, 0, sequence, *raws)
    except struct.error:
        raise PayloadError(f"cannot pack COMMAND: mode {mode!r}, sequence {sequence!r} (uint32)") from None


def decode_command(data: bytes, scaling: Scaling) -> Command:
    """The command in a COMMAND v1 payload, with the same checks as ``encode_command`` (the board's side)."""
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


def encode_telemetry(telemetry: Telemetry, scaling: Scaling) -> bytes:
    """The TELEMETRY v1 payload (the boards' side; the simulated hardware uses it).

    Measured values are not limited to the command range, only to what the field can hold.
    :raises PayloadError: a non-finite value, a value the field cannot hold, flags beyond uint16.
    """
    t = telemetry
    mode = _mode(t.mode)
    fields = (
        _int(t.position, scaling.position.lsb, INT32_MIN, INT32_MAX, "position"),
        _int(t.velocity, scaling.velocity.lsb, INT32_MIN, INT32_MAX, "velocity"),
        _int(t.effort, scaling.effort.lsb, INT32_MIN, INT32_MAX, "effort"),
        _int(t.current, CURRENT_LSB, INT32_MIN, INT32_MAX, "current"),
        _int(t.temperature, TEMPERATURE_LSB, INT16_MIN, INT16_MAX, "temperature"),
    )
    try:
        return TELEMETRY_LAYOUT.pack(
            PayloadType.TELEMETRY, TELEMETRY_VERSION, mode, 0, t.status, t.errors, t.sequence, t.board_time_us,
            *fields, 0,
        )  # fmt: skip
    except struct.error as error:
        raise PayloadError(
            f"telemetry integer field out of range (status/errors uint16, sequence uint32, board_time_us uint64): "
            f"status={t.status!r} errors={t.errors!r} sequence={t.sequence!r} board_time_us={t.board_time_us!r}"
        ) from error


def decode_telemetry(data: bytes, scaling: Scaling) -> Telemetry:
    """The telemetry in a TELEMETRY v1 payload. Unknown flag bits are kept (IntFlag), unknown modes refused."""
    _check_header(data, PayloadType.TELEMETRY, TELEMETRY_VERSION, TELEMETRY_LAYOUT)
    (_, _, mode, reserved, status, errors, sequence, time_us, pos, vel, eff, cur, temp, reserved2) = (
        TELEMETRY_LAYOUT.unpack(data)
    )
    if reserved or reserved2:
        raise PayloadError(f"reserved fields of TELEMETRY are {reserved}/{reserved2}, must be 0")
    return Telemetry(
        _mode(mode),
        StatusFlags(status),
        ErrorFlags(errors),
        sequence,
        time_us,
        pos * scaling.position.lsb,
        vel * scaling.velocity.lsb,
        eff * scaling.effort.lsb,
        cur * CURRENT_LSB,
        temp * TEMPERATURE_LSB,
    )


# --------------------------------------------------------------------------------------------------- vectorised

COMMAND_DTYPE: Final = np.dtype(
    [("type", "u1"), ("version", "u1"), ("mode", "u1"), ("reserved", "u1"), ("sequence", "<u4")]
    + [(name, "<i4") for name in ("setpoint", "velocity_ff", "effort_ff")]
)
TELEMETRY_DTYPE: Final = np.dtype(
    [("type", "u1"), ("version", "u1"), ("mode", "u1"), ("reserved", "u1"), ("status", "<u2"), ("errors", "<u2")]
    + [("sequence", "<u4"), ("board_time_us", "<u8")]
    + [(name, "<i4") for name in ("position", "velocity", "effort", "current")]
    + [("temperature", "<i2"), ("reserved2", "<u2")]
)
assert COMMAND_DTYPE.itemsize == COMMAND_LAYOUT.size
assert TELEMETRY_DTYPE.itemsize == TELEMETRY_LAYOUT.size

MAX_MODE: Final = max(CommandMode)
"""The highest mode a board may report: telemetry naming another is invalid."""
_USED_MASK: Final = np.array([_USED_FIELDS[m] for m in CommandMode], dtype=bool)  # (mode, field)


class ScalingTable:
    """The scalings of n boards as (3, n) arrays (rows: position, velocity, effort), for the batch codecs."""

    def __init__(self, scalings: Sequence[Scaling], names: Sequence[str] | None = None) -> None:
        self.names = tuple(names) if names is not None else tuple(f"#{i}" for i in range(len(scalings)))
        if len(self.names) != len(scalings):
            raise ValueError(f"{len(self.names)} names for {len(scalings)} scalings")
        self.lsb = np.array([[q.lsb for q in s] for s in scalings], dtype=float).T.copy()
        self.low = np.array([[q.low for q in s] for s in scalings], dtype=float).T.copy()
        self.high = np.array([[q.high for q in s] for s in scalings], dtype=float).T.copy()

    def __len__(self) -> int:
        return len(self.names)


def encode_commands(
    modes: Sequence[int] | np.ndarray,
    setpoint: Sequence[float] | np.ndarray,
    velocity_ff: Sequence[float] | np.ndarray,
    effort_ff: Sequence[float] | np.ndarray,
    *,
    sequence: int,
    table: ScalingTable,
) -> list[bytes]:
    """COMMAND v1 payloads for n boards at once (one per board, in table order); the same checks and bytes as
    ``encode_command``, raising ``PayloadError`` naming the first offending board."""
    n = len(table)
    mode_array = np.asarray(modes)
    if (
        mode_array.shape != (n,)
        or mode_array.dtype.kind not in "iu"
        or not ((mode_array >= 0) & (mode_array <= MAX_MODE)).all()
    ):
        raise PayloadError(f"modes must be {n} CommandMode values, got {modes!r}")
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
        value, name, board = float(values[row, col]), _COMMAND_FIELDS[row], table.names[col]
        if not used[row, col]:
            reason = f"must be 0 in {CommandMode(int(mode_array[col])).name} mode"
        elif not finite[row, col]:
            reason = "is not finite"
        else:
            reason = f"is outside the wire range [{float(table.low[row, col])}, {float(table.high[row, col])}]"
        raise PayloadError(f"{board}: {name} = {value!r} {reason}")
    raw = np.rint(np.where(used, values, 0.0) / table.lsb).astype(np.int32)
    out = np.zeros(n, dtype=COMMAND_DTYPE)
    out["type"], out["version"] = PayloadType.COMMAND, COMMAND_VERSION
    out["mode"], out["sequence"] = mode_array, sequence
    out["setpoint"], out["velocity_ff"], out["effort_ff"] = raw
    blob, size = out.tobytes(), COMMAND_LAYOUT.size
    return [blob[i : i + size] for i in range(0, n * size, size)]


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


def decode_telemetry_many(payloads: Sequence[bytes], table: ScalingTable) -> TelemetryArrays:
    """Decode one TELEMETRY v1 payload per board (in table order) with the checks of ``decode_telemetry``."""
    if len(payloads) != len(table):
        raise PayloadError(f"{len(payloads)} payloads for {len(table)} boards")
    size = TELEMETRY_LAYOUT.size
    for name, data in zip(table.names, payloads, strict=True):
        if len(data) != size or data[0] != PayloadType.TELEMETRY or data[1] != TELEMETRY_VERSION:
            try:
                _check_header(data, PayloadType.TELEMETRY, TELEMETRY_VERSION, TELEMETRY_LAYOUT)
            except PayloadError as error:
                raise PayloadError(f"{name}: {error}") from None
    rec = np.frombuffer(b"".join(payloads), dtype=TELEMETRY_DTYPE)
    bad = (rec["mode"] > max(CommandMode)) | (rec["reserved"] != 0) | (rec["reserved2"] != 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise PayloadError(f"{table.names[i]}: unknown mode {rec['mode'][i]} or nonzero reserved fields")
    return TelemetryArrays(
        rec["mode"].copy(),
        rec["status"].copy(),
        rec["errors"].copy(),
        rec["sequence"].copy(),
        rec["board_time_us"].copy(),
        rec["position"] * table.lsb[0],
        rec["velocity"] * table.lsb[1],
        rec["effort"] * table.lsb[2],
        rec["current"] * CURRENT_LSB,
        rec["temperature"] * TEMPERATURE_LSB,
    )


def decode_telemetry_of(
    payloads: Sequence[bytes] | bytes, boards: np.ndarray, table: ScalingTable
) -> tuple[np.ndarray, TelemetryArrays]:
    """Decode TELEMETRY v1 payloads (a list, or already joined) of the boards at ``boards`` (table indices, any
    subset) in one pass.

    The payloads must have the size, type and version bytes of TELEMETRY v1 (checked per frame by the caller,
    cheaply); returns which of them also pass the mode and reserved-field checks of ``decode_telemetry`` (the
    rest are to be dropped) and the arrays of all of them, in SI units.
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


def encode_telemetry_many(telemetry: TelemetryArrays, table: ScalingTable) -> list[bytes]:
    """TELEMETRY v1 payloads for n boards at once (the simulated boards' side); the bytes of ``encode_telemetry``.

    :raises PayloadError: a non-finite value or one its field cannot hold, naming the first offending board.
    """
    n = len(table)
    values = np.array(
        [telemetry.position, telemetry.velocity, telemetry.effort, telemetry.current, telemetry.temperature],
        dtype=float,
    )
    if values.shape != (5, n):
        raise PayloadError(f"telemetry must have {n} values per field")
    lsb = np.vstack([table.lsb, np.full((1, n), CURRENT_LSB), np.full((1, n), TEMPERATURE_LSB)])
    raw = np.rint(values / lsb)
    bounds = np.array([[INT32_MIN, INT32_MAX]] * 4 + [[INT16_MIN, INT16_MAX]], dtype=float)
    ok = np.isfinite(raw) & (raw >= bounds[:, :1]) & (raw <= bounds[:, 1:])
    if not ok.all():
        row, col = np.argwhere(~ok)[0]
        field = ("position", "velocity", "effort", "current", "temperature")[row]
        raise PayloadError(f"{table.names[col]}: telemetry {field} = {values[row, col]!r} cannot be encoded")
    out = np.zeros(n, dtype=TELEMETRY_DTYPE)
    out["type"], out["version"] = PayloadType.TELEMETRY, TELEMETRY_VERSION
    out["mode"], out["status"], out["errors"] = telemetry.mode, telemetry.status, telemetry.errors
    out["sequence"], out["board_time_us"] = telemetry.sequence, telemetry.board_time_us
    out["position"], out["velocity"], out["effort"], out["current"] = raw[:4].astype(np.int32)
    out["temperature"] = raw[4].astype(np.int16)
    blob, size = out.tobytes(), TELEMETRY_LAYOUT.size
    return [blob[i : i + size] for i in range(0, n * size, size)]
