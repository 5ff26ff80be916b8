"""NDLCom over classic CAN through python-can (socketcan on the robot, the ``virtual`` interface in tests).

Mapping (docs/protocol.md): each NDLCom frame, exactly as encoded for the byte stream (flags and escapes
included), is cut into consecutive 8-byte CAN data frames (the last one shorter) with the standard 11-bit
arbitration id ``base_id + sender``. A node owns the id of its NDLCom address, so frames of one sender arrive in
order on one id and the receiver reassembles each id's byte stream with its own NDLCom decoder: any interleaving
of several senders is harmless, and a lost CAN frame only costs the NDLCom frames it touched (the FCS and the
next flag catch it). The lowest NDLCom address wins arbitration.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable
from typing import Any, Final

import can

from rh5_bringup.hardware.ndlcom.codec import ESCAPE, ESCAPE_XOR, FLAG, FrameError
from rh5_bringup.hardware.transports.base import Transport, TransportInitError, TransportOperationError

__all__ = ["CAN_DATA_BYTES", "DEFAULT_BASE_ID", "CanTransport", "can_messages", "frame_sender"]

DEFAULT_BASE_ID: Final = 0x400
"""Arbitration ids 0x400..0x4FF carry NDLCom (0x400 + sender id)."""
CAN_DATA_BYTES: Final = 8
MAX_STANDARD_ID: Final = 0x7FF


def frame_sender(frame: bytes) -> int:
    """The sender id of an encoded frame, read through the escaping.

    :raises FrameError: ``frame`` does not start like an encoded NDLCom frame.
    """
    if len(frame) < 3 or frame[0] != FLAG:
        raise FrameError("an encoded frame starts with the 0x7E flag and a header")
    i = 2 if frame[1] == ESCAPE else 1  # skip the receiver byte (escaped or not)
    if i + 1 >= len(frame):
        raise FrameError("encoded frame too short for a sender byte")
    sender = frame[i + 1]
    if sender == ESCAPE:
        if i + 2 >= len(frame):
            raise FrameError("encoded frame too short for a sender byte")
        sender = frame[i + 2] ^ ESCAPE_XOR
    return sender


def can_messages(frame: bytes, base_id: int = DEFAULT_BASE_ID) -> list[can.Message]:
    """The CAN data frames that carry one encoded NDLCom frame (the mapping of this module)."""
    arbitration_id = base_id + frame_sender(frame)
    return [
        can.Message(arbitration_id=arbitration_id, data=frame[i : i + CAN_DATA_BYTES], is_extended_id=False)
        for i in range(0, len(frame), CAN_DATA_BYTES)
    ]


class CanTransport(Transport):
    """NDLCom frames over a python-can bus.

    :param interface: python-can interface name ('socketcan' on the robot, 'virtual' in tests).
    :param channel: python-can channel ('can0'; any name for 'virtual', where equal names share a bus).
    :param base_id: first of the 256 standard ids carrying NDLCom; ids outside the range are ignored.
    :param receivers: as for ``Transport``: deliver only frames addressed to these ids (and broadcast).
    :param send_timeout: seconds one CAN frame may wait for the bus (python-can's send timeout).
    :param bus_kwargs: passed to ``can.Bus`` (e.g. ``bitrate``).
    :raises TransportInitError: python-can cannot open the interface.
    """

    def __init__(
        self,
        interface: str = "virtual",
        channel: str = "rh5",
        *,
        base_id: int = DEFAULT_BASE_ID,
        receivers: Iterable[int] | None = None,
        send_timeout: float = 0.01,
        **bus_kwargs: Any,
    ) -> None:
        if not 0 <= base_id <= MAX_STANDARD_ID - 0xFF:
            raise ValueError(f"base_id 0x{base_id:x}: base_id + 255 must be a standard 11-bit id (<= 0x7ff)")
        try:
            bus = can.Bus(interface=interface, channel=channel, **bus_kwargs)
        except (can.CanError, OSError, ImportError, ValueError) as error:
            raise TransportInitError(f"cannot open CAN interface {interface!r} channel {channel!r}: {error}") from error
        self._bus = bus
        self._interface, self._channel = interface, channel
        self._base_id = base_id
        self._send_timeout = send_timeout
        try:
            super().__init__(receivers)
        except BaseException:
            bus.shutdown()
            raise

    @property
    def base_id(self) -> int:
        """Arbitration id of NDLCom sender 0."""
        return self._base_id

    def fileno(self) -> int:
        """The bus's descriptor where python-can has one (socketcan), else NotImplementedError."""
        fd = self._bus.fileno()
        if fd < 0:
            raise NotImplementedError(f"python-can interface {self._interface!r} has no file descriptor")
        return fd

    def _recv_bytes(self, timeout: float | None) -> tuple[bytes, Hashable] | None:
        try:
            message = self._bus.recv(timeout)
        except can.CanError as error:
            raise TransportOperationError(f"CAN receive on {self._describe()} failed: {error}") from error
        if message is None:
            return None
        stream = message.arbitration_id
        if (
            message.is_error_frame
            or message.is_remote_frame
            or message.is_extended_id
            or not self._base_id <= stream <= self._base_id + 0xFF
        ):
            return b"", stream  # not NDLCom: counted as a foreign chunk
        return bytes(message.data), stream

    def _send_bytes(self, data: bytes) -> None:
        try:
            messages = can_messages(data, self._base_id)
        except FrameError as error:
            raise TransportOperationError(f"cannot send over CAN: {error}") from error
        try:
            for message in messages:
                self._bus.send(message, timeout=self._send_timeout)
        except can.CanError as error:
            raise TransportOperationError(f"CAN send on {self._describe()} failed: {error}") from error

    def _close(self) -> None:
        self._bus.shutdown()

    def _describe(self) -> str:
        return f"{self._interface}:{self._channel} ids 0x{self._base_id:03x}+"
