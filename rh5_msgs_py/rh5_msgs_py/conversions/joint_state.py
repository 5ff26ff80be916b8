"""sensor_msgs/JointState <-> numpy arrays, and the 1 kHz codec that reuses one message."""

from __future__ import annotations

import array
from collections.abc import Iterable, Sequence
from typing import Final, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from sensor_msgs.msg import JointState

from rh5_msgs_py.array_types import FloatArray

from .joint_names import JointNameIndex, _name_index
from .times import _CDR_STAMP_OFFSET, _STAMP, _set_stamp, _split_ns

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
