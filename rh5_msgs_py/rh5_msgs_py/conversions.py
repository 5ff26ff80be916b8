"""Vectorised conversions between numpy arrays and the common_interfaces messages of the suite.

Float64 array fields are filled from ``array.array('d', ndarray.tobytes())`` (a memcpy, ~0.4 us for 32
values) and read with ``np.frombuffer`` (zero copy). Assigning an ndarray to a rosidl field iterates it
element by element (~2.5 us) and fails the field check when ROS_PYTHON_CHECK_FIELDS=1. For 1 kHz paths,
:class:`JointStateCodec` reuses one message and writes into its arrays in place (bench/msgs_roundtrip.py).
Values are converted, not judged: NaN passes through; shapes, names and times are checked.
"""

from __future__ import annotations

import array
import operator
import struct
from collections.abc import Callable, Iterable, Mapping, Sequence
from enum import IntEnum
from functools import lru_cache
from types import MappingProxyType
from typing import Final, NamedTuple

import numpy as np
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Transform, Twist, WrenchStamped
from numpy.typing import ArrayLike, NDArray
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import (
    JointTrajectory,
    JointTrajectoryPoint,
    MultiDOFJointTrajectory,
    MultiDOFJointTrajectoryPoint,
)

__all__ = [
    "BaseTrajectoryArrays",
    "JointNameIndex",
    "JointStateArrays",
    "JointStateCodec",
    "JointTrajectoryArrays",
    "Level",
    "Status",
    "base_trajectory_from_msg",
    "base_trajectory_to_msg",
    "diagnostics_from_msg",
    "diagnostics_to_msg",
    "duration_to_ns",
    "duration_to_s",
    "joint_state_from_msg",
    "joint_state_to_msg",
    "joint_trajectory_from_msg",
    "joint_trajectory_to_msg",
    "seconds_to_ns",
    "status_from_msg",
    "status_to_msg",
    "time_to_ns",
    "time_to_s",
    "to_duration_msg",
    "to_time_msg",
    "wrench_from_msg",
    "wrench_to_msg",
]

NS_PER_S: Final = 1_000_000_000
_INT32_MIN: Final = -(2**31)
_INT32_MAX: Final = 2**31 - 1
_MAX_LISTED: Final = 8  # names listed in an error message before "... (+k more)"

FloatArray = NDArray[np.float64]

# --------------------------------------------------------------------------------------------------
# time


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


# --------------------------------------------------------------------------------------------------
# names


def _listing(names: Sequence[str]) -> str:
    shown = ", ".join(names[:_MAX_LISTED])
    more = len(names) - _MAX_LISTED
    return f"[{shown}{f', ... (+{more} more)' if more > 0 else ''}]"


def _unique_names(names: Iterable[str], what: str) -> tuple[str, ...]:
    out = tuple(names)
    if len(set(out)) != len(out):
        dups = sorted({n for n in out if out.count(n) > 1})
        msg = f"{what}: duplicate joint names {_listing(dups)}"
        raise ValueError(msg)
    return out


class JointNameIndex:
    """Maps the joint order of incoming messages onto one fixed order, caching one index per message order.

    ``index(msg_names)`` returns None when the order already matches (the fast path: one tuple
    comparison) and otherwise an index array ``idx`` with ``values_in_our_order = msg_values[idx]``.
    """

    _CACHE_SIZE: Final = 16

    def __init__(self, names: Iterable[str], *, allow_extra: bool = False, what: str = "message") -> None:
        self.names: Final = _unique_names(names, what)
        self.allow_extra: Final = allow_extra
        self.what: Final = what
        self._cache: dict[tuple[str, ...], tuple[NDArray[np.intp], ...]] = {}

    def index(self, msg_names: Sequence[str]) -> NDArray[np.intp] | None:
        """Index array from the message's order into ours, None if identical; ValueError naming bad joints."""
        entry = self._entry(msg_names)
        return None if entry is None else entry[0]

    def _entry(self, msg_names: Sequence[str]) -> tuple[NDArray[np.intp], ...] | None:
        """None for the same order, else the index into 1, 2 and 3 concatenated fields (flat, for one gather)."""
        key = msg_names if type(msg_names) is tuple else tuple(msg_names)
        if key == self.names:
            return None
        entry = self._cache.get(key)
        if entry is None:
            idx = self._build(key)
            entry = tuple((np.arange(rows)[:, None] * len(key) + idx).ravel() for rows in (1, 2, 3))
            if len(self._cache) >= self._CACHE_SIZE:
                self._cache.clear()
            self._cache[key] = entry
        return entry

    def _build(self, key: tuple[str, ...]) -> NDArray[np.intp]:
        position = {name: i for i, name in enumerate(key)}
        if len(position) != len(key):
            _unique_names(key, self.what)
        missing = [n for n in self.names if n not in position]
        wanted = set(self.names)
        unknown = [] if self.allow_extra else [n for n in key if n not in wanted]
        if missing or unknown:
            parts = []
            if missing:
                parts.append(f"missing joints {_listing(missing)}")
            if unknown:
                parts.append(f"unknown joints {_listing(unknown)}")
            msg = f"{self.what}: joint names do not match the expected {len(self.names)} joints: {'; '.join(parts)}"
            raise ValueError(msg)
        return np.array([position[n] for n in self.names], dtype=np.intp)


@lru_cache(maxsize=64)
def _name_index(names: tuple[str, ...], allow_extra: bool, what: str) -> JointNameIndex:
    return JointNameIndex(names, allow_extra=allow_extra, what=what)


# --------------------------------------------------------------------------------------------------
# sensor_msgs/JointState


_JS_FIELDS: Final = ("position", "velocity", "effort")


class JointStateArrays(NamedTuple):
    """Position, velocity and effort of a JointState in a requested joint order; None where the message had none."""

    position: FloatArray | None
    velocity: FloatArray | None
    effort: FloatArray | None


def _vector(value: ArrayLike, n: int, what: str) -> FloatArray:
    vec = np.asarray(value, dtype=np.float64)
    if vec.shape != (n,):
        msg = f"{what} must have shape ({n},), got {vec.shape}"
        raise ValueError(msg)
    return vec


def _as_double_array(value: ArrayLike | None, n: int, what: str) -> array.array[float]:
    """Field value for a rosidl float64[]: a memcpy'd array('d'), empty for None."""
    if value is None:
        return array.array("d")
    return array.array("d", _vector(value, n, what).tobytes())


def _read_doubles(field: Sequence[float]) -> FloatArray:
    """Zero-copy float64 view of a rosidl float64[] field (array('d') as deserialised; anything else copied)."""
    if type(field) is array.array:
        return np.frombuffer(field, dtype=np.float64)
    return np.asarray(field, dtype=np.float64)


def joint_state_to_msg(
    names: Sequence[str],
    position: ArrayLike | None,
    velocity: ArrayLike | None = None,
    effort: ArrayLike | None = None,
    *,
    stamp_ns: int = 0,
    msg: JointState | None = None,
    frame_id: str = "",
) -> JointState:
    """sensor_msgs/JointState from arrays in ``names`` order (None -> empty field); fills ``msg`` if given."""
    n = len(names)
    out = JointState() if msg is None else msg
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    out.name = list(names)
    out.position = _as_double_array(position, n, "JointState.position")
    out.velocity = _as_double_array(velocity, n, "JointState.velocity")
    out.effort = _as_double_array(effort, n, "JointState.effort")
    return out


def _decode_joint_state(msg: JointState, index: JointNameIndex) -> JointStateArrays:
    """Gather the non-empty fields of ``msg`` into one fresh (k, n) block in ``index`` order."""
    names = msg.name
    entry = index._entry(names)
    n_msg = len(names)
    fields = pos, vel, eff = msg.position, msg.velocity, msg.effort
    if (
        n_msg
        and len(pos) == n_msg
        and len(vel) == n_msg
        and len(eff) == n_msg
        and type(pos) is type(vel) is type(eff) is array.array
    ):  # the common case, spelled out: all three fields as deserialised
        flat = np.frombuffer(b"".join(fields))  # float64 is frombuffer's default dtype (and the fastest call)
        flat = flat.copy() if entry is None else flat[entry[2]]
        rows = flat.reshape(3, len(index.names))
        return JointStateArrays(rows[0], rows[1], rows[2])
    present = []
    for k, field in enumerate(fields):
        size = len(field)
        if size:
            if size != n_msg:
                text = f"{index.what}: JointState.{_JS_FIELDS[k]} has {size} values for {n_msg} names"
                raise ValueError(text)
            present.append(k)
    if not present:
        return JointStateArrays(None, None, None)
    data = [fields[k] for k in present]
    if all(type(f) is array.array for f in data):
        flat = np.frombuffer(b"".join(data))  # float64 is frombuffer's default dtype (and the fastest call)
    else:
        flat = np.concatenate([np.asarray(f, dtype=np.float64) for f in data])
    flat = flat.copy() if entry is None else flat[entry[len(present) - 1]]
    rows = flat.reshape(len(present), len(index.names))
    out: list[FloatArray | None] = [None, None, None]
    for r, k in enumerate(present):
        out[k] = rows[r]
    return JointStateArrays(*out)


def joint_state_from_msg(msg: JointState, names: Sequence[str], *, allow_extra: bool = False) -> JointStateArrays:
    """Arrays of a JointState reordered to ``names`` (fresh copies); ValueError naming missing/unknown joints.

    The name -> index mapping is cached per (requested order, message order); with ``allow_extra`` the
    message may carry joints beyond ``names``.
    """
    return _decode_joint_state(msg, _name_index(tuple(names), allow_extra, "JointState"))


class JointStateCodec:
    """JointState <-> arrays for one fixed joint order, for 1 kHz loops: no per-call allocation on encode.

    ``encode`` writes into the arrays of one preallocated message and returns that same message each
    call: publish it (rclpy serialises synchronously) or copy it, but do not keep it or assign its
    fields. ``decode`` returns fresh arrays, safe to hand to another thread as a snapshot.
    """

    def __init__(
        self, names: Iterable[str], *, frame_id: str = "", allow_extra: bool = False, what: str = "JointState"
    ) -> None:
        self.index: Final = JointNameIndex(names, allow_extra=allow_extra, what=what)
        self.names: Final = self.index.names
        n = len(self.names)
        # check_fields=True makes the array setters store an array('d') by reference instead of copying,
        # so the numpy views below stay bound to what gets serialised.
        self.msg: Final = JointState(check_fields=True)
        self.msg.header.frame_id = frame_id
        self.msg.name = list(self.names)
        self._arrays = tuple(array.array("d", bytes(8 * n)) for _ in range(3))
        self._views = tuple(np.frombuffer(a, dtype=np.float64) for a in self._arrays)
        self._empty = array.array("d")
        self._present = [False, False, False]
        self._shape: Final = (n,)
        self._templates: dict[tuple[bool, bool, bool], tuple[bytes, list[int | None]]] = {}

    def encode(
        self,
        position: ArrayLike | None,
        velocity: ArrayLike | None = None,
        effort: ArrayLike | None = None,
        *,
        stamp_ns: int = 0,
    ) -> JointState:
        """Fill the codec's message (arrays in ``names`` order, None -> empty field) and return it."""
        msg = self.msg
        stamp = msg.header.stamp
        stamp.sec, stamp.nanosec = _split_ns(stamp_ns, "header.stamp")
        for k, value in enumerate((position, velocity, effort)):
            if value is None:
                if self._present[k]:
                    self._set_field(k, self._empty)
                continue
            vec = np.asarray(value, dtype=np.float64)
            if vec.shape != self._shape:
                text = f"{self.index.what}: {_JS_FIELDS[k]} must have shape {self._shape}, got {vec.shape}"
                raise ValueError(text)
            self._views[k][:] = vec
            if not self._present[k]:
                self._set_field(k, self._arrays[k])
        return msg

    def encode_serialized(
        self,
        position: FloatArray,
        velocity: FloatArray | None = None,
        effort: FloatArray | None = None,
        *,
        stamp_ns: int = 0,
    ) -> bytes:
        """The CDR bytes of what ``encode`` builds, for ``Publisher.publish`` (which sends bytes as they are).

        A 1 kHz publisher spends most of a message on converting the 32 joint names into the C message each
        time; here rclpy serialises a template once per combination of present fields, and each call only
        writes the stamp and the arrays into a copy of it, at the offsets the template showed.
        """
        present = (True, velocity is not None, effort is not None)
        template = self._templates.get(present)
        if template is None:
            template = self._templates[present] = self._serialized_template(present)
        blob, offsets = template
        out = bytearray(blob)
        sec, nanosec = _split_ns(stamp_ns, "header.stamp")
        _STAMP.pack_into(out, _CDR_STAMP_OFFSET, sec, nanosec)
        view = np.frombuffer(out, dtype=np.uint8)
        size = 8 * len(self.names)
        for offset, value in zip(offsets, (position, velocity, effort), strict=True):
            if offset is not None:
                vec = np.asarray(value, dtype="<f8")
                if vec.shape != self._shape:
                    text = f"{self.index.what}: arrays must have shape {self._shape}, got {vec.shape}"
                    raise ValueError(text)
                view[offset : offset + size] = vec.view(np.uint8)
        return bytes(out)

    def _serialized_template(self, present: tuple[bool, bool, bool]) -> tuple[bytes, list[int | None]]:
        """rclpy's own serialisation of a message with distinct marker values, and where each array lies in it."""
        from rclpy.serialization import serialize_message  # noqa: PLC0415 (rclpy's C extension, loaded lazily)

        n = len(self.names)
        markers = [np.arange(n, dtype="<f8") + 0.125 + 1000.0 * (k + 1) if on else None for k, on in enumerate(present)]
        msg = JointState(name=list(self.names))
        msg.header.frame_id = self.msg.header.frame_id
        for k, values in enumerate(markers):
            if values is not None:
                setattr(msg, _JS_FIELDS[k], values.tolist())
        blob = serialize_message(msg)
        offsets = [None if values is None else blob.find(values.tobytes()) for values in markers]
        if any(o is not None and o < 0 for o in offsets) or blob[:2] != b"\x00\x01":
            msg = "JointState: rclpy's serialisation is not the little-endian CDR this codec writes into"
            raise RuntimeError(msg)
        return blob, offsets

    def _set_field(self, k: int, value: array.array[float]) -> None:
        setattr(self.msg, _JS_FIELDS[k], value)
        self._present[k] = value is not self._empty

    def decode(self, msg: JointState) -> JointStateArrays:
        """Arrays of ``msg`` in the codec's order (fresh copies); ValueError naming missing/unknown joints."""
        return _decode_joint_state(msg, self.index)


# --------------------------------------------------------------------------------------------------
# trajectory_msgs/JointTrajectory


class JointTrajectoryArrays(NamedTuple):
    """A JointTrajectory as arrays: knot times (N,) in s from ``stamp_ns`` and (N, n) fields (None if absent)."""

    joint_names: tuple[str, ...]
    times: FloatArray
    positions: FloatArray | None
    velocities: FloatArray | None
    accelerations: FloatArray | None
    efforts: FloatArray | None
    stamp_ns: int = 0
    frame_id: str = ""


_POINT_FIELDS: Final = ("positions", "velocities", "accelerations", "effort")


def _matrix_rows(value: ArrayLike | None, shape: tuple[int, int], what: str) -> list[bytes] | None:
    """(N, n) array -> one bytes block per row (None stays None)."""
    if value is None:
        return None
    mat = np.asarray(value, dtype=np.float64)
    if mat.shape != shape:
        msg = f"{what} must have shape {shape}, got {mat.shape}"
        raise ValueError(msg)
    flat = mat.tobytes()
    step = 8 * shape[1]
    return [flat[i : i + step] for i in range(0, step * shape[0], step)]


def joint_trajectory_to_msg(
    names: Sequence[str],
    times_s: ArrayLike,
    positions: ArrayLike | None,
    *,
    velocities: ArrayLike | None = None,
    accelerations: ArrayLike | None = None,
    efforts: ArrayLike | None = None,
    stamp_ns: int = 0,
    frame_id: str = "",
) -> JointTrajectory:
    """trajectory_msgs/JointTrajectory from knot times (N,) [s, strictly increasing] and (N, n) arrays."""
    joint_names = _unique_names(names, "JointTrajectory")
    ns = _times_to_ns(times_s, "JointTrajectory")
    shape = (len(ns), len(joint_names))
    rows = [
        (attr, _matrix_rows(value, shape, f"JointTrajectory.{label}"))
        for attr, label, value in zip(
            _POINT_FIELDS,
            ("positions", "velocities", "accelerations", "efforts"),
            (positions, velocities, accelerations, efforts),
            strict=True,
        )
    ]
    rows = [(attr, r) for attr, r in rows if r is not None]
    secs, nanosecs = np.divmod(ns, NS_PER_S)
    points = []
    for i, (sec, nanosec) in enumerate(zip(secs.tolist(), nanosecs.tolist(), strict=True)):
        point = JointTrajectoryPoint()
        for attr, data in rows:
            setattr(point, attr, array.array("d", data[i]))
        tfs = point.time_from_start
        tfs.sec = sec
        tfs.nanosec = nanosec
        points.append(point)
    out = JointTrajectory()
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    out.joint_names = list(joint_names)
    out.points = points
    return out


def _point_times_ns(points: Sequence[JointTrajectoryPoint | MultiDOFJointTrajectoryPoint]) -> NDArray[np.int64]:
    return np.fromiter(
        (p.time_from_start.sec * NS_PER_S + p.time_from_start.nanosec for p in points),
        dtype=np.int64,
        count=len(points),
    )


def _stack_field(points: Sequence[JointTrajectoryPoint], attr: str, n: int, what: str) -> FloatArray | None:
    """(N, n) array of one point field; None if every point leaves it empty; ValueError if ragged."""
    fields = [getattr(p, attr) for p in points]
    sizes = np.fromiter((len(f) for f in fields), dtype=np.int64, count=len(fields))
    if not sizes.any():
        return None
    bad = np.flatnonzero(sizes != n)
    if bad.size:
        i = int(bad[0])
        msg = f"{what}: point {i} has {sizes[i]} {attr} for {n} joints (a field must be empty in every point or full)"
        raise ValueError(msg)
    if all(type(f) is array.array for f in fields):
        return np.frombuffer(b"".join(fields), dtype=np.float64).reshape(len(fields), n)
    return np.array([_read_doubles(f) for f in fields], dtype=np.float64).reshape(len(fields), n)


def joint_trajectory_from_msg(
    msg: JointTrajectory, names: Sequence[str] | None = None, *, allow_extra: bool = False
) -> JointTrajectoryArrays:
    """Arrays of a JointTrajectory, columns reordered to ``names`` if given; ValueError for ragged points,
    non-increasing times or missing/unknown joints."""
    what = "JointTrajectory"
    msg_names = _unique_names(msg.joint_names, what)
    idx = None if names is None else _name_index(tuple(names), allow_extra, what).index(msg_names)
    out_names = msg_names if names is None else tuple(names)
    points = msg.points
    ns = _point_times_ns(points)
    _check_increasing(ns, what)
    fields = []
    for attr in _POINT_FIELDS:
        mat = _stack_field(points, attr, len(msg_names), what)
        fields.append(mat if mat is None or idx is None else mat[:, idx])
    return JointTrajectoryArrays(
        out_names, ns / NS_PER_S, *fields, stamp_ns=time_to_ns(msg.header.stamp), frame_id=msg.header.frame_id
    )


def joint_trajectory_from_cdr(
    data: bytes, names: Sequence[str] | None = None, *, allow_extra: bool = False
) -> JointTrajectoryArrays:
    """``joint_trajectory_from_msg`` of a serialised JointTrajectory (a raw subscription's bytes).

    rclpy's conversion of a long trajectory into message objects is one C call that holds the interpreter
    lock for tens of ms (6301 points: ~60 ms), which a 1 kHz loop of the same process cannot wait for. Here
    the points, which share one layout, are read as strided numpy views of the bytes; anything else (ragged
    points, another encoding) goes through rclpy's own deserialisation.
    """
    fast = _trajectory_points_view(data)
    if fast is None:
        from rclpy.serialization import deserialize_message  # noqa: PLC0415 (rclpy's C extension, lazily)

        return joint_trajectory_from_msg(deserialize_message(data, JointTrajectory), names, allow_extra=allow_extra)
    stamp_ns, frame_id, msg_names, ns, fields = fast
    what = "JointTrajectory"
    msg_names = _unique_names(msg_names, what)
    idx = None if names is None else _name_index(tuple(names), allow_extra, what).index(msg_names)
    _check_increasing(ns, what)
    if idx is not None:
        fields = [None if f is None else f[:, idx] for f in fields]
    out_names = msg_names if names is None else tuple(names)
    return JointTrajectoryArrays(out_names, ns / NS_PER_S, *fields, stamp_ns=stamp_ns, frame_id=frame_id)


_U32: Final = struct.Struct("<I")


def _trajectory_points_view(
    data: bytes,
) -> tuple[int, str, tuple[str, ...], NDArray[np.int64], list[FloatArray | None]] | None:
    """Stamp, frame id, names, point times (ns) and the four (N, n) fields of a little-endian CDR JointTrajectory
    whose points all have the same layout; None when it is not one (the caller deserialises it the slow way)."""
    if len(data) < 16 or data[:2] != b"\x00\x01":
        return None

    def align(pos: int, size: int) -> int:
        return pos + (-(pos - 4) % size)  # CDR alignment counts from the end of the 4-byte encapsulation

    def string(pos: int) -> tuple[str, int]:
        pos = align(pos, 4)
        (size,) = _U32.unpack_from(data, pos)
        return data[pos + 4 : pos + 4 + size - 1].decode(), pos + 4 + size

    try:
        sec, nanosec = _STAMP.unpack_from(data, 4)
        frame_id, pos = string(12)
        pos = align(pos, 4)
        (count,) = _U32.unpack_from(data, pos)
        pos += 4
        names = []
        for _ in range(count):
            name, pos = string(pos)
            names.append(name)
        pos = align(pos, 4)
        (points,) = _U32.unpack_from(data, pos)
        first = pos + 4
        groups = _point_groups(data, first, points, align)
    except (struct.error, UnicodeDecodeError, IndexError):
        return None
    if groups is None:
        return None
    sizes = [groups[0][0][k][1] for k in range(4)]  # each field: empty in every point, or one value per joint
    if any(n not in (0, len(names)) for n in sizes) or any(g[0][k][1] != sizes[k] for g in groups for k in range(4)):
        return None
    fields: list[FloatArray | None] = [np.empty((points, n)) if n and points else None for n in sizes]
    times = np.empty((points, 2), dtype=np.int64)
    for layout, stride, rows in groups:
        count = len(range(points)[rows])
        for k, n in enumerate(sizes):
            offset = layout[k][0]
            if not (np.ndarray((count,), "<u4", data, offset, (stride,)) == n).all():
                return None  # ragged points
            if fields[k] is not None:
                fields[k][rows] = np.ndarray((count, n), "<f8", data, align(offset + 4, 8), (stride, 8))
        times[rows] = np.ndarray((count, 2), "<u4", data, layout[4][0], (stride, 4))
    seconds = times[:, 0].astype(np.int32).astype(np.int64)  # int32 seconds, uint32 nanoseconds
    return sec * NS_PER_S + nanosec, frame_id, tuple(names), seconds * NS_PER_S + times[:, 1], fields


def _point_groups(
    data: bytes, first: int, points: int, align: Callable[[int, int], int]
) -> list[tuple[list[tuple[int, int]], int, slice]] | None:
    """The points as groups with one layout each at a constant stride: (layout of the group's first point, in
    offsets into ``data``; stride; which points). A point's padding depends on where it starts modulo 8, and a
    point whose size is not a multiple of 8 moves the next one to the other alignment: so either every point
    has one layout, or the first differs from the rest, or even and odd points alternate. None otherwise."""
    if points == 0:
        layout, _ = _point_layout(data, first, align)
        return [(layout, 8, slice(0, 0))]
    layout0, start1 = _point_layout(data, first, align)
    stride0 = start1 - first
    if points == 1 or (start1 - first) % 8 == 0:
        groups = [(layout0, stride0, slice(0, points))]
        end = first + points * stride0
    else:
        layout1, start2 = _point_layout(data, start1, align)
        stride1 = start2 - start1
        if stride1 % 8 == 0:  # from the second point on, one alignment
            groups = [(layout0, stride0, slice(0, 1)), (layout1, stride1, slice(1, points))]
            end = start1 + (points - 1) * stride1
        else:  # even and odd points alternate
            period = stride0 + stride1
            groups = [(layout0, period, slice(0, points, 2)), (layout1, period, slice(1, points, 2))]
            end = first + (points // 2) * period + (points % 2) * stride0
    return groups if end <= len(data) else None


def _point_layout(data: bytes, pos: int, align: Callable[[int, int], int]) -> tuple[list[tuple[int, int]], int]:
    """Where one JointTrajectoryPoint's four sequences (offset of the length word, length) and its
    time_from_start lie, and where the next point begins."""
    layout = []
    for _ in range(4):
        pos = align(pos, 4)
        (n,) = _U32.unpack_from(data, pos)
        layout.append((pos, n))
        pos = pos + 4
        if n:
            pos = align(pos, 8) + 8 * n
    pos = align(pos, 4)
    layout.append((pos, 0))
    return layout, pos + 8


# --------------------------------------------------------------------------------------------------
# trajectory_msgs/MultiDOFJointTrajectory (floating base)


class BaseTrajectoryArrays(NamedTuple):
    """Floating-base trajectory as arrays: times (N,) s, positions (N,3) m, quaternions (N,4) xyzw,
    twists/accelerations (N,6) linear xyz then angular xyz (None if absent)."""

    times: FloatArray
    positions: FloatArray
    quaternions_xyzw: FloatArray
    twists: FloatArray | None
    accelerations: FloatArray | None
    joint_name: str = "floating_base"
    frame_id: str = "world"
    stamp_ns: int = 0


def _rows_as_lists(value: ArrayLike | None, shape: tuple[int, int], what: str) -> list[list[float]] | None:
    if value is None:
        return None
    mat = np.asarray(value, dtype=np.float64)
    if mat.shape != shape:
        msg = f"{what} must have shape {shape}, got {mat.shape}"
        raise ValueError(msg)
    return mat.tolist()  # type: ignore[no-any-return]


def _twist(values: list[float]) -> Twist:
    twist = Twist()
    lin, ang = twist.linear, twist.angular
    lin.x, lin.y, lin.z, ang.x, ang.y, ang.z = values
    return twist


def base_trajectory_to_msg(
    times_s: ArrayLike,
    positions: ArrayLike,
    quaternions_xyzw: ArrayLike,
    *,
    twists: ArrayLike | None = None,
    accelerations: ArrayLike | None = None,
    joint_name: str = "floating_base",
    frame_id: str = "world",
    stamp_ns: int = 0,
) -> MultiDOFJointTrajectory:
    """trajectory_msgs/MultiDOFJointTrajectory with one joint (the floating base) from arrays.

    Frames are passed through unchanged: the producer documents in which frame its twists are.
    """
    what = "MultiDOFJointTrajectory"
    ns = _times_to_ns(times_s, what)
    n_points = len(ns)
    pos = _rows_as_lists(positions, (n_points, 3), f"{what}.positions")
    quat = _rows_as_lists(quaternions_xyzw, (n_points, 4), f"{what}.quaternions_xyzw")
    vel = _rows_as_lists(twists, (n_points, 6), f"{what}.twists")
    acc = _rows_as_lists(accelerations, (n_points, 6), f"{what}.accelerations")
    assert pos is not None  # for the type checker
    assert quat is not None
    secs, nanosecs = np.divmod(ns, NS_PER_S)
    points = []
    for i, (sec, nanosec) in enumerate(zip(secs.tolist(), nanosecs.tolist(), strict=True)):
        transform = Transform()
        tr, rot = transform.translation, transform.rotation
        tr.x, tr.y, tr.z = pos[i]
        rot.x, rot.y, rot.z, rot.w = quat[i]
        point = MultiDOFJointTrajectoryPoint()
        point.transforms = [transform]
        if vel is not None:
            point.velocities = [_twist(vel[i])]
        if acc is not None:
            point.accelerations = [_twist(acc[i])]
        tfs = point.time_from_start
        tfs.sec = sec
        tfs.nanosec = nanosec
        points.append(point)
    out = MultiDOFJointTrajectory()
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    out.joint_names = [joint_name]
    out.points = points
    return out


def _twists_of(points: Sequence[MultiDOFJointTrajectoryPoint], attr: str, j: int, n: int) -> FloatArray | None:
    sizes = [len(getattr(p, attr)) for p in points]
    if not any(sizes):
        return None
    for i, size in enumerate(sizes):
        if size != n:
            msg = f"MultiDOFJointTrajectory: point {i} has {size} {attr} for {n} joints"
            raise ValueError(msg)
    return np.array(
        [
            (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z)
            for t in (getattr(p, attr)[j] for p in points)
        ],
        dtype=np.float64,
    ).reshape(len(points), 6)


def base_trajectory_from_msg(msg: MultiDOFJointTrajectory, joint_name: str | None = None) -> BaseTrajectoryArrays:
    """Arrays of one joint of a MultiDOFJointTrajectory (``joint_name``, or the only joint if None)."""
    what = "MultiDOFJointTrajectory"
    names = _unique_names(msg.joint_names, what)
    if joint_name is None:
        if len(names) != 1:
            text = f"{what}: has {len(names)} joints {_listing(names)}; say which one is the floating base"
            raise ValueError(text)
        j = 0
    elif joint_name in names:
        j = names.index(joint_name)
    else:
        text = f"{what}: no joint {joint_name!r} among {_listing(names)}"
        raise ValueError(text)
    points = msg.points
    ns = _point_times_ns(points)
    _check_increasing(ns, what)
    for i, p in enumerate(points):
        if len(p.transforms) != len(names):
            text = f"{what}: point {i} has {len(p.transforms)} transforms for {len(names)} joints"
            raise ValueError(text)
    transforms = [p.transforms[j] for p in points]
    positions = np.array(
        [(t.translation.x, t.translation.y, t.translation.z) for t in transforms], dtype=np.float64
    ).reshape(len(points), 3)
    quats = np.array(
        [(t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w) for t in transforms], dtype=np.float64
    ).reshape(len(points), 4)
    return BaseTrajectoryArrays(
        ns / NS_PER_S,
        positions,
        quats,
        _twists_of(points, "velocities", j, len(names)),
        _twists_of(points, "accelerations", j, len(names)),
        joint_name=names[j],
        frame_id=msg.header.frame_id,
        stamp_ns=time_to_ns(msg.header.stamp),
    )


# --------------------------------------------------------------------------------------------------
# geometry_msgs/WrenchStamped


def wrench_to_msg(
    wrench6: ArrayLike, frame_id: str = "", stamp_ns: int = 0, *, msg: WrenchStamped | None = None
) -> WrenchStamped:
    """geometry_msgs/WrenchStamped from (6,) = force xyz [N], torque xyz [Nm]; fills ``msg`` if given."""
    fx, fy, fz, tx, ty, tz = _vector(wrench6, 6, "wrench").tolist()
    out = WrenchStamped() if msg is None else msg
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    force, torque = out.wrench.force, out.wrench.torque
    force.x, force.y, force.z = fx, fy, fz
    torque.x, torque.y, torque.z = tx, ty, tz
    return out


def wrench_from_msg(msg: WrenchStamped) -> FloatArray:
    """(6,) array from a WrenchStamped: force xyz, torque xyz."""
    f, t = msg.wrench.force, msg.wrench.torque
    return np.array((f.x, f.y, f.z, t.x, t.y, t.z), dtype=np.float64)


# --------------------------------------------------------------------------------------------------
# diagnostic_msgs


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
