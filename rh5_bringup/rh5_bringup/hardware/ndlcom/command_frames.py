"""The driver's command frames of one cycle, for every board at once: the bytes ``FrameEncoder.encode`` would send.

Per cycle the driver sends one COMMAND frame to each of the 32 boards. Frame by frame in Python that is most
of a 1 kHz cycle here; this writer fills one preallocated (boards x payload) byte array through a structured
view and hands it to the C framing (``_framing.encode_frames``: header, FCS, escaping, the frame counters).
Values must already lie in the wire range (``fits``): the driver clamps to the intersection of the actuator
limits and the wire ranges, so nothing needs checking per cycle.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from rh5_bringup.hardware.ndlcom._framing import encode_frames
from rh5_bringup.hardware.ndlcom.codec import FrameEncoder
from rh5_bringup.hardware.ndlcom.payloads import COMMAND_LAYOUT, COMMAND_VERSION, CommandMode, PayloadType
from rh5_bringup.hardware.ndlcom.scaling import ScalingTable

_PAYLOAD_DTYPE: Final = np.dtype(
    {
        "names": ["mode", "sequence", "setpoint", "velocity_ff", "effort_ff"],
        "formats": ["u1", "<u4", "<i4", "<i4", "<i4"],
        "offsets": [2, 4, 8, 12, 16],
        "itemsize": COMMAND_LAYOUT.size,
    }
)
"""The fields of a COMMAND v1 payload that change per cycle (type, version and reserved stay as set)."""


class CommandFrames:
    """COMMAND v1 frames from one encoder to a fixed set of boards (``receivers``, in table order)."""

    def __init__(self, encoder: FrameEncoder, receivers: list[int], table: ScalingTable) -> None:
        if len(set(receivers)) != len(receivers) or len(receivers) != len(table):
            msg = f"need one distinct receiver per board of the table, got {receivers}"
            raise ValueError(msg)
        self._counters = encoder.counter._next  # advanced in place, as FrameEncoder.encode does
        self._receivers = bytes(receivers)
        self._sender = encoder.sender
        payloads = np.zeros((len(receivers), COMMAND_LAYOUT.size), dtype=np.uint8)
        payloads[:, 0], payloads[:, 1] = PayloadType.COMMAND, COMMAND_VERSION
        self._payloads = payloads
        self._fields = payloads.reshape(-1).view(_PAYLOAD_DTYPE)
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
        return encode_frames(self._receivers, self._sender, self._counters, self._payloads, COMMAND_LAYOUT.size)
