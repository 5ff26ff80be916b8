"""diagnostic_msgs: a status as a plain record (Status, Level) <-> DiagnosticStatus and DiagnosticArray."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import IntEnum
from types import MappingProxyType
from typing import Final, NamedTuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from .times import _set_stamp


class Level(IntEnum):
    """DiagnosticStatus levels with their wire values."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


_NO_VALUES: Final[Mapping[str, object]] = MappingProxyType({})


class Status(NamedTuple):
    """One diagnostic status; ``values`` become KeyValue pairs (``str(value)``), in order."""

    name: str
    level: Level
    message: str
    values: Mapping[str, object] = _NO_VALUES
    hardware_id: str = ""


def status_to_msg(status: Status) -> DiagnosticStatus:
    """diagnostic_msgs/DiagnosticStatus from a Status (level checked against OK/WARN/ERROR/STALE)."""
    level = Level(status.level)
    out = DiagnosticStatus()
    out.level = bytes((level,))
    out.name = status.name
    out.message = status.message
    out.hardware_id = status.hardware_id
    out.values = [KeyValue(key=str(k), value=str(v)) for k, v in status.values.items()]
    return out


def status_from_msg(msg: DiagnosticStatus) -> Status:
    """Status from a DiagnosticStatus; values as strings; ValueError for a level outside 0..3."""
    raw = msg.level
    code = raw[0] if isinstance(raw, bytes | bytearray) else int(raw)
    try:
        level = Level(code)
    except ValueError:
        text = f"DiagnosticStatus {msg.name!r}: level {code} is not one of OK=0, WARN=1, ERROR=2, STALE=3"
        raise ValueError(text) from None
    values = MappingProxyType({kv.key: kv.value for kv in msg.values})
    return Status(msg.name, level, msg.message, values, msg.hardware_id)


def diagnostics_to_msg(statuses: Iterable[Status], stamp_ns: int = 0) -> DiagnosticArray:
    """diagnostic_msgs/DiagnosticArray of ``statuses``, stamped ``stamp_ns``."""
    out = DiagnosticArray()
    _set_stamp(out.header, stamp_ns)
    out.status = [status_to_msg(s) for s in statuses]
    return out


def diagnostics_from_msg(msg: DiagnosticArray) -> list[Status]:
    """Statuses of a DiagnosticArray, in order."""
    return [status_from_msg(s) for s in msg.status]
