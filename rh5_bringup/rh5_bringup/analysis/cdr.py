"""Vectorised CDR decoding of the 1 kHz streams (JointState, PoseStamped, WrenchStamped) of a bag.

A minute at 1 kHz is 60 000 messages per stream; deserialising each one into a message object
costs ~25 us. Messages of one stream share their layout (same names, same frame id), so equal-length
messages are stacked into one byte matrix and the float64 columns are read at fixed offsets. A message
whose layout differs from its group's first one is parsed on its own; big-endian CDR, which no
ROS 2 platform of the suite produces, is refused with ValueError so the caller can fall back.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import NDArray

from rh5_msgs_py.array_types import FloatArray

_LE_HEADERS: Final = (b"\x00\x01", b"\x00\x03")  # CDR_LE, PL_CDR_LE
_UINT32: Final = struct.Struct("<I")
_PAYLOAD_START: Final = 4  # alignment in CDR counts from the end of the encapsulation header


class CdrError(ValueError):
    """A message that is not the little-endian CDR encoding of the expected type."""


def _align(pos: int, size: int) -> int:
    rel = pos - _PAYLOAD_START
    return pos + (-rel % size)


def _check_header(raw: bytes | memoryview) -> None:
    if len(raw) < 16 or bytes(raw[:2]) not in _LE_HEADERS:
        msg = f"not little-endian CDR (encapsulation {bytes(raw[:2]).hex() or 'missing'}, {len(raw)} bytes)"
        raise CdrError(msg)


def _read_string(raw: bytes, pos: int) -> tuple[str, int]:
    pos = _align(pos, 4)
    (size,) = _UINT32.unpack_from(raw, pos)
    end = pos + 4 + size
    if size == 0 or end > len(raw):
        msg = f"string at byte {pos} runs past the message ({len(raw)} bytes)"
        raise CdrError(msg)
    return raw[pos + 4 : end - 1].decode("utf-8"), end


def _header_end(raw: bytes) -> int:
    """Byte offset after std_msgs/Header (stamp + frame_id)."""
    _check_header(raw)
    _, end = _read_string(raw, 12)
    return end


def _stamps_ns(matrix: NDArray[np.uint8]) -> NDArray[np.int64]:
    sec = np.ascontiguousarray(matrix[:, 4:8]).view("<i4").ravel().astype(np.int64)
    nsec = np.ascontiguousarray(matrix[:, 8:12]).view("<u4").ravel().astype(np.int64)
    return sec * 1_000_000_000 + nsec


def _floats(matrix: NDArray[np.uint8], offset: int, count: int) -> FloatArray:
    block = np.ascontiguousarray(matrix[:, offset : offset + 8 * count])
    return block.view("<f8").reshape(len(matrix), count).astype(np.float64)


def _groups_by_length(raws: Sequence[bytes]) -> dict[int, list[int]]:
    groups: dict[int, list[int]] = {}
    for i, raw in enumerate(raws):
        groups.setdefault(len(raw), []).append(i)
    return groups


def _matrix(raws: Sequence[bytes], rows: list[int]) -> NDArray[np.uint8]:
    length = len(raws[rows[0]])
    return np.frombuffer(b"".join([raws[i] for i in rows]), dtype=np.uint8).reshape(len(rows), length)


# --- sensor_msgs/JointState ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class JointStateLayout:
    """Where the fields of one JointState encoding sit: names, (offset, count) per float64 array, and the
    byte ranges that define the layout (encapsulation, string sizes and bytes, sequence counts)."""

    names: tuple[str, ...]
    arrays: tuple[tuple[int, int], tuple[int, int], tuple[int, int]]  # position, velocity, effort
    structure: tuple[tuple[int, int], ...]

    def structure_mask(self, length: int) -> NDArray[np.bool_]:
        """True for the bytes that must be equal in two messages of this layout.

        Padding is left out: the serializer does not initialise it, so it differs between messages.
        """
        mask = np.zeros(length, dtype=bool)
        for start, end in self.structure:
            mask[start:end] = True
        return mask


def joint_state_layout(raw: bytes) -> JointStateLayout:
    """Parse one JointState's CDR bytes far enough to know its names and array offsets.

    Trailing bytes are allowed: rclpy's serialized size can exceed what the fields use.
    """
    pos = _header_end(raw)
    structure = [(0, 2), (12, pos)]
    pos = _align(pos, 4)
    (n_names,) = _UINT32.unpack_from(raw, pos)
    structure.append((pos, pos + 4))
    pos += 4
    names = []
    for _ in range(n_names):
        start = _align(pos, 4)
        name, pos = _read_string(raw, pos)
        structure.append((start, pos))
        names.append(name)
    arrays = []
    for _ in range(3):
        pos = _align(pos, 4)
        if pos + 4 > len(raw):
            msg = f"JointState encoding runs past the message ({len(raw)} bytes)"
            raise CdrError(msg)
        (count,) = _UINT32.unpack_from(raw, pos)
        structure.append((pos, pos + 4))
        pos += 4
        if count:
            pos = _align(pos, 8)
        arrays.append((pos, count))
        pos += 8 * count
    if pos > len(raw):
        msg = f"JointState encoding ends at byte {pos}, message has {len(raw)}"
        raise CdrError(msg)
    return JointStateLayout(tuple(names), (arrays[0], arrays[1], arrays[2]), tuple(structure))


@dataclass(frozen=True)
class JointStateBlock:
    """Messages (by index into the decoded batch) that share one name list."""

    rows: NDArray[np.intp]
    names: tuple[str, ...]
    stamps_ns: NDArray[np.int64]
    position: FloatArray | None  # (rows, len(names)); None where the messages left the array empty
    velocity: FloatArray | None
    effort: FloatArray | None


def decode_joint_states(raws: Sequence[bytes]) -> list[JointStateBlock]:
    """Decode a batch of JointState CDR messages into blocks of equal layout (CdrError on a bad one)."""
    blocks: list[JointStateBlock] = []
    for rows in _groups_by_length(raws).values():
        pending = rows
        while pending:  # normally one pass: every message of a stream has the first one's layout
            layout = joint_state_layout(raws[pending[0]])
            matrix = _matrix(raws, pending)
            keep = np.flatnonzero(layout.structure_mask(matrix.shape[1]))
            structure = matrix[:, keep]
            same = (structure == structure[0]).all(axis=1)
            all_same = bool(same.all())
            sub = matrix if all_same else matrix[same]
            fields = [_floats(sub, off, n) if n else None for off, n in layout.arrays]
            rows_taken = np.asarray(pending, dtype=np.intp)
            blocks.append(
                JointStateBlock(
                    rows_taken if all_same else rows_taken[same],
                    layout.names,
                    _stamps_ns(sub),
                    fields[0],
                    fields[1],
                    fields[2],
                )
            )
            pending = [] if all_same else rows_taken[~same].tolist()
    return blocks


# --- header + fixed float64 block (PoseStamped: 7, WrenchStamped: 6) -------------------------------------------------


def decode_stamped_floats(raws: Sequence[bytes], count: int) -> tuple[NDArray[np.int64], FloatArray]:
    """Stamps (ns) and the ``count`` float64 after the header of each message, in input order.

    geometry_msgs/PoseStamped is position xyz + orientation xyzw (7), WrenchStamped force + torque (6).
    """
    stamps = np.zeros(len(raws), dtype=np.int64)
    values = np.zeros((len(raws), count))
    for rows in _groups_by_length(raws).values():
        matrix = _matrix(raws, rows)
        if len(raws[rows[0]]) < 16 or not ((matrix[:, 0] == 0) & np.isin(matrix[:, 1], (1, 3))).all():
            msg = "a message of the batch is not little-endian CDR"
            raise CdrError(msg)
        frame_sizes = np.ascontiguousarray(matrix[:, 12:16]).view("<u4").ravel()
        for size in np.unique(frame_sizes):
            sub = np.flatnonzero(frame_sizes == size)
            offset = _align(16 + int(size), 8)
            if size == 0 or offset + 8 * count > matrix.shape[1]:
                msg = f"expected {count} float64 after the header: the message has {matrix.shape[1]} bytes"
                raise CdrError(msg)
            index = np.asarray(rows)[sub]
            stamps[index] = _stamps_ns(matrix[sub])
            values[index] = _floats(matrix[sub], offset, count)
    return stamps, values
