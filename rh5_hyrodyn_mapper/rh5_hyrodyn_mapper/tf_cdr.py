"""A tf2_msgs/TFMessage kept serialised (CDR), whose rotations, translations and stamps are rewritten in place.

rclpy converts a Python TFMessage of 33 transforms into its C form field by field on every publish: about 1 ms
of CPU here, most of the state publisher's cost at 50 Hz. The frame names never change, so the message is
serialised once with a distinct marker value in every field that does; each publish then writes the new values
into those byte positions with one numpy assignment per kind and publishes the bytes (rclpy publishes a
``bytes`` as already serialised).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from rclpy.serialization import serialize_message

from rh5_msgs_py.array_types import FloatArray


def _positions(data: bytes, markers: Sequence[bytes]) -> npt.NDArray[np.intp]:
    """Byte offsets of each marker, each found exactly once."""
    out = []
    for marker in markers:
        at = data.find(marker)
        if at < 0 or data.find(marker, at + 1) >= 0:
            msg = "a marker value is missing from or repeated in the serialised message"
            raise ValueError(msg)
        out.append(at)
    return np.array(out, dtype=np.intp)


class SerializedTf:
    """A TFMessage of fixed frames with writable translations, rotations and stamps."""

    def __init__(self, message_type: type, transform_type: type, frames: Sequence[tuple[str, str]]) -> None:
        n = len(frames)
        marks = 1.0e9 + np.arange(n * 7, dtype=np.float64).reshape(n, 7)  # x y z, qx qy qz qw: all distinct
        message = message_type(transforms=[transform_type() for _ in frames])
        for k, (transform, (parent, child)) in enumerate(zip(message.transforms, frames, strict=True)):
            transform.header.frame_id, transform.child_frame_id = parent, child
            transform.header.stamp.sec, transform.header.stamp.nanosec = 2_000_000_000 - k, 3_000_000_000 - k
            t, r = transform.transform.translation, transform.transform.rotation
            t.x, t.y, t.z, r.x, r.y, r.z, r.w = (float(v) for v in marks[k])
        data = serialize_message(message)
        doubles = _positions(data, [struct.pack("<d", v) for v in marks.ravel()])
        self._doubles = (doubles[:, None] + np.arange(8)).reshape(n, 7 * 8)
        seconds = _positions(data, [struct.pack("<i", 2_000_000_000 - k) for k in range(n)])
        nanoseconds = _positions(data, [struct.pack("<I", 3_000_000_000 - k) for k in range(n)])
        self._stamps = np.concatenate([seconds[:, None] + np.arange(4), nanoseconds[:, None] + np.arange(4)], axis=1)
        self.buffer = bytearray(data)
        self._bytes = np.frombuffer(self.buffer, dtype=np.uint8)
        self.poses: FloatArray = np.zeros((n, 7))
        """Translation and rotation (x, y, z, qx, qy, qz, qw) of every transform, written by ``serialized``."""
        self.poses[:, 6] = 1.0

    def serialized(self, sec: int, nanosec: int) -> bytes:
        """The message with ``poses`` and the stamp (every transform's) written in."""
        self._bytes[self._doubles] = self.poses.astype("<f8").view(np.uint8).reshape(self._doubles.shape)
        stamp = np.frombuffer(struct.pack("<iI", sec, nanosec), dtype=np.uint8)
        self._bytes[self._stamps] = stamp
        return bytes(self.buffer)
