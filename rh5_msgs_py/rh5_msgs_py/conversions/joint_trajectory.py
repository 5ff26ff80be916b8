"""trajectory_msgs/JointTrajectory <-> numpy arrays, also straight from its CDR bytes."""

from __future__ import annotations

import array
import struct
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Final, NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from trajectory_msgs.msg import (
    JointTrajectory,
    JointTrajectoryPoint,
    MultiDOFJointTrajectoryPoint,
)

from rh5_msgs_py.array_types import FloatArray

from ._common import NS_PER_S
from .joint_names import _name_index, _unique_names
from .joint_state import _read_doubles
from .times import _STAMP, _check_increasing, _set_stamp, _times_to_ns, time_to_ns

T = TypeVar("T")
M = TypeVar("M")


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


def _checked_matrix(value: ArrayLike, shape: tuple[int, int], what: str) -> FloatArray:
    """``value`` as a float64 array of exactly ``shape``, or ValueError naming ``what``."""
    mat = np.asarray(value, dtype=np.float64)
    if mat.shape != shape:
        msg = f"{what} must have shape {shape}, got {mat.shape}"
        raise ValueError(msg)
    return mat


def _matrix_rows(value: ArrayLike | None, shape: tuple[int, int], what: str) -> list[bytes] | None:
    """(N, n) array -> one bytes block per row (None stays None)."""
    if value is None:
        return None
    mat = _checked_matrix(value, shape, what)
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
    points = []
    for i, point in enumerate(_timed_points(JointTrajectoryPoint, ns)):
        for attr, data in rows:
            setattr(point, attr, array.array("d", data[i]))
        points.append(point)
    return _trajectory(JointTrajectory(), stamp_ns, frame_id, list(joint_names), points)


def _timed_points(point_class: type[T], ns: NDArray[np.int64]) -> Iterator[T]:
    """One new ``point_class`` per time in ``ns``, its ``time_from_start`` set: both trajectory builders' points."""
    secs, nanosecs = np.divmod(ns, NS_PER_S)
    for sec, nanosec in zip(secs.tolist(), nanosecs.tolist(), strict=True):
        point = point_class()
        tfs = point.time_from_start
        tfs.sec = sec
        tfs.nanosec = nanosec
        yield point


def _trajectory(out: M, stamp_ns: int, frame_id: str, joint_names: list[str], points: list[Any]) -> M:
    """``out`` with its header, joint names and points: how both trajectory builders finish."""
    _set_stamp(out.header, stamp_ns)
    out.header.frame_id = frame_id
    out.joint_names = joint_names
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
