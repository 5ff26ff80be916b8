"""NDLCom, the framed link to the RH5 actuator boards: framing codec, payload layouts and the board map.

Pure library code (no ROS, no sockets); docs/protocol.md is the wire specification.
"""

from rh5_bringup.hardware.ndlcom.codec import (
    BROADCAST,
    Frame,
    FrameCounter,
    FrameDecoder,
    FrameEncoder,
    FrameError,
    encode_frame,
    fcs16,
)

__all__ = [
    "BROADCAST",
    "Frame",
    "FrameCounter",
    "FrameDecoder",
    "FrameEncoder",
    "FrameError",
    "encode_frame",
    "fcs16",
]
