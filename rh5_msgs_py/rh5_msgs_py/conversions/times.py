"""Times and durations: nanosecond integers and seconds <-> builtin_interfaces Time and Duration, header stamps."""

from __future__ import annotations

import operator
import struct
from typing import Final

import numpy as np
from builtin_interfaces.msg import Duration, Time
from numpy.typing import ArrayLike, NDArray
from std_msgs.msg import Header

from ._common import _INT32_MAX, _INT32_MIN, NS_PER_S

_STAMP: Final = struct.Struct("<iI")
_CDR_STAMP_OFFSET: Final = 4
"""header.stamp comes first in a JointState, right after the 4-byte CDR encapsulation header."""


def _split_ns(ns: int, what: str) -> tuple[int, int]:
    """Integer nanoseconds -> (sec, nanosec) as builtin_interfaces wants them (nanosec in [0, 1e9))."""
    sec, nanosec = divmod(operator.index(ns), NS_PER_S)
    if not _INT32_MIN <= sec <= _INT32_MAX:
        msg = f"{what}: {ns} ns is outside the int32 seconds range of builtin_interfaces"
        raise ValueError(msg)
    return sec, nanosec


def seconds_to_ns(seconds: float) -> int:
    """Seconds (float) -> integer nanoseconds, rounded to the nearest nanosecond."""
    value = float(seconds)
    if not np.isfinite(value):
        msg = f"time must be finite, got {value}"
        raise ValueError(msg)
    return round(value * NS_PER_S)


def to_time_msg(ns: int, msg: Time | None = None) -> Time:
    """builtin_interfaces/Time from integer nanoseconds (filled into ``msg`` if given)."""
    sec, nanosec = _split_ns(ns, "Time")
    out = Time() if msg is None else msg
    out.sec = sec
    out.nanosec = nanosec
    return out


def time_to_ns(msg: Time) -> int:
    """builtin_interfaces/Time -> integer nanoseconds."""
    return msg.sec * NS_PER_S + msg.nanosec


def time_to_s(msg: Time) -> float:
    """builtin_interfaces/Time -> float seconds."""
    return msg.sec + msg.nanosec * 1e-9


def to_duration_msg(seconds: float | None = None, *, ns: int | None = None, msg: Duration | None = None) -> Duration:
    """builtin_interfaces/Duration from float ``seconds`` or integer ``ns`` (exactly one of them)."""
    if (seconds is None) == (ns is None):
        text = "to_duration_msg: give exactly one of seconds or ns"
        raise TypeError(text)
    total = seconds_to_ns(seconds) if seconds is not None else operator.index(ns)  # type: ignore[arg-type]
    sec, nanosec = _split_ns(total, "Duration")
    out = Duration() if msg is None else msg
    out.sec = sec
    out.nanosec = nanosec
    return out


def duration_to_ns(msg: Duration) -> int:
    """builtin_interfaces/Duration -> integer nanoseconds."""
    return msg.sec * NS_PER_S + msg.nanosec


def duration_to_s(msg: Duration) -> float:
    """builtin_interfaces/Duration -> float seconds."""
    return msg.sec + msg.nanosec * 1e-9


def _set_stamp(header: Header, stamp_ns: int) -> None:
    stamp = header.stamp
    stamp.sec, stamp.nanosec = _split_ns(stamp_ns, "header.stamp")


def _times_to_ns(times_s: ArrayLike, what: str) -> NDArray[np.int64]:
    """Knot times (N,) in s -> int64 ns; finite, within int32 seconds and strictly increasing."""
    times = np.asarray(times_s, dtype=np.float64)
    if times.ndim != 1:
        msg = f"{what}: times must have shape (N,), got {times.shape}"
        raise ValueError(msg)
    if not np.all(np.isfinite(times)) or np.any(np.abs(times) >= 2.0**31):
        msg = f"{what}: times must be finite and within +-2**31 s"
        raise ValueError(msg)
    ns = np.rint(times * NS_PER_S).astype(np.int64)
    _check_increasing(ns, what)
    return ns


def _check_increasing(ns: NDArray[np.int64], what: str) -> None:
    bad = np.flatnonzero(np.diff(ns) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        msg = (
            f"{what}: time_from_start must increase strictly (at nanosecond resolution): "
            f"point {i} at {ns[i] * 1e-9:.9f} s, point {i - 1} at {ns[i - 1] * 1e-9:.9f} s"
        )
        raise ValueError(msg)
