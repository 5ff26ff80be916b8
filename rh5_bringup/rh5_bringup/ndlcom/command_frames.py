"""The driver's command frames of one cycle, for every board at once: the bytes ``FrameEncoder.encode`` would send.

Per cycle the driver sends one COMMAND frame to each of the 32 boards. Frame by frame in Python that is most
of a 1 kHz cycle here; this writer fills one preallocated (boards x frame) byte array through a structured
view (header, payload fields, FCS), computes every frame's FCS as one table gather and one XOR reduction
(the CRC of a fixed-length message is affine in its bytes, ``codec.fcs_tables``), and escapes only the rows
that contain a flag or escape byte. Values must already lie in the wire range (``fits``): the driver clamps
to the intersection of the actuator limits and the wire ranges, so nothing needs checking per cycle.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from rh5_bringup.ndlcom.codec import ESCAPE, FLAG, HEADER, FrameEncoder, escape_body, fcs_tables
from rh5_bringup.ndlcom.payloads import COMMAND_LAYOUT, COMMAND_VERSION, CommandMode, PayloadType, ScalingTable

_BODY: Final = HEADER.size + COMMAND_LAYOUT.size
_WIRE_DTYPE: Final = np.dtype(
    {
        "names": ["counter", "mode", "sequence", "setpoint", "velocity_ff", "effort_ff", "fcs"],
        "formats": ["u1", "u1", "<u4", "<i4", "<i4", "<i4", "<u2"],
        "offsets": [3, 7, 9, 13, 17, 21, 1 + _BODY],
        "itemsize": _BODY + 4,
    }
)
"""One frame on the wire without escapes: flag, receiver, sender, counter, length, payload (type, version,
mode, reserved, sequence, setpoint, velocity_ff, effort_ff), FCS, flag; the fields that change per cycle."""
_NEEDS_ESCAPE: Final = np.zeros(256, dtype=bool)
_NEEDS_ESCAPE[[FLAG, ESCAPE]] = True


class CommandFrames:
    """COMMAND v1 frames from one encoder to a fixed set of boards (``receivers``, in table order)."""

    def __init__(self, encoder: FrameEncoder, receivers: list[int], table: ScalingTable) -> None:
        if len(set(receivers)) != len(receivers) or len(receivers) != len(table):
            msg = f"need one distinct receiver per board of the table, got {receivers}"
            raise ValueError(msg)
        self._counters = np.frombuffer(encoder.counter._next, dtype=np.uint8)
        self._receivers = np.array(receivers, dtype=np.intp)
        n = len(receivers)
        template = np.zeros((n, _BODY + 4), dtype=np.uint8)
        template[:, 0] = template[:, -1] = FLAG
        template[:, 1], template[:, 2], template[:, 4] = receivers, encoder.sender, COMMAND_LAYOUT.size
        template[:, 5], template[:, 6] = PayloadType.COMMAND, COMMAND_VERSION
        self._template = template
        self._wire = template.copy()
        self._fields = self._wire.reshape(-1).view(_WIRE_DTYPE)
        self._body = self._wire[:, 1 : 1 + _BODY]
        tables, self._fcs_init = fcs_tables(_BODY)
        self._fcs_table = tables.reshape(-1)
        self._fcs_index = np.empty((n, _BODY), dtype=np.intp)
        self._positions = np.arange(_BODY, dtype=np.intp) * 256
        self._inv_lsb = 1.0 / table.lsb
        self.low, self.high = table.low.copy(), table.high.copy()
        """The wire range per (setpoint, velocity_ff, effort_ff) row and board: what ``fits`` checks."""

    def fits(self, setpoint: np.ndarray, velocity_ff: np.ndarray, effort_ff: np.ndarray) -> bool:
        """Whether the values are finite and inside the boards' wire ranges (``encode_commands``' own check)."""
        values = np.array([setpoint, velocity_ff, effort_ff])
        return bool(((values >= self.low) & (values <= self.high)).all())  # NaN compares False

    def frames(
        self,
        mode: CommandMode,
        sequence: int,
        setpoint: np.ndarray | None = None,
        velocity_ff: np.ndarray | None = None,
        effort_ff: np.ndarray | None = None,
    ) -> list[bytes]:
        """This cycle's frames, one per board: ``mode`` for all, with the setpoints in POSITION_FF (which must
        ``fit``) and zeros in HOLD/OFF. Advances each receiver's frame counter, as ``FrameEncoder.encode`` does."""
        if not 0 <= sequence <= 0xFFFFFFFF:
            msg = f"sequence {sequence!r} is outside uint32"
            raise ValueError(msg)
        fields = self._fields
        fields["counter"] = self._counters[self._receivers]
        self._counters[self._receivers] += 1  # uint8: wraps at 256
        fields["mode"], fields["sequence"] = int(mode), sequence
        if mode == CommandMode.POSITION_FF:
            scale = self._inv_lsb
            fields["setpoint"] = np.rint(setpoint * scale[0])
            fields["velocity_ff"] = np.rint(velocity_ff * scale[1])
            fields["effort_ff"] = np.rint(effort_ff * scale[2])
        elif mode in (CommandMode.HOLD, CommandMode.OFF):
            fields["setpoint"] = fields["velocity_ff"] = fields["effort_ff"] = 0
        else:
            msg = f"CommandFrames writes POSITION_FF, HOLD or OFF frames, not {mode!r}"
            raise ValueError(msg)
        index = np.add(self._body, self._positions, out=self._fcs_index, dtype=np.intp)
        fcs = np.bitwise_xor.reduce(self._fcs_table[index], axis=1)
        fields["fcs"] = fcs ^ self._fcs_init
        wire = self._wire
        blob, step = wire.tobytes(), wire.shape[1]
        frames = [blob[k : k + step] for k in range(0, len(blob), step)]
        for k in np.flatnonzero(_NEEDS_ESCAPE[wire[:, 1:-1]].any(axis=1)):
            frames[k] = escape_body(frames[k][1:-1])
        return frames
