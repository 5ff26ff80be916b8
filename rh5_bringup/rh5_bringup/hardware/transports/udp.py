"""NDLCom over UDP/IPv4: the link to the central FPGA/ARM router (and, on 127.0.0.1, to the simulated hardware).

A datagram carries one or more whole NDLCom frames back to back (each with both flags); no frame spans two
datagrams. ``send_frames`` packs frames into datagrams of at most ``max_datagram`` bytes (default 1472, one
Ethernet MTU without IP fragmentation). UDP gives no delivery or ordering guarantee: the frame counters expose
losses. Receiving is non-blocking with the timeout done by ``select``.
"""

from __future__ import annotations

import select
import socket
from collections.abc import Hashable, Iterable
from typing import Final

from rh5_bringup.hardware.ndlcom.codec import MAX_ENCODED_SIZE
from rh5_bringup.hardware.transports.base import Transport, TransportInitError, TransportOperationError

__all__ = ["DEFAULT_MAX_DATAGRAM", "UdpTransport"]

DEFAULT_MAX_DATAGRAM: Final = 1472
"""1500-byte Ethernet MTU minus the IPv4 (20) and UDP (8) headers."""
_RECV_SIZE: Final = 65535

Address = tuple[str, int]


class UdpTransport(Transport):
    """NDLCom frames in UDP datagrams between ``local`` (bound) and ``remote``.

    :param local: (host, port) to bind; port 0 picks a free one (see ``local_address``).
    :param remote: where frames go; ``None`` answers the peer of the most recent datagram (the router side).
    :param receivers: as for ``Transport``: deliver only frames addressed to these ids (and broadcast).
    :param max_datagram: upper bound of one datagram when ``send_frames`` packs several frames.
    :param receive_buffer: SO_RCVBUF in bytes, or ``None`` for the system default.
    :raises TransportInitError: the socket cannot be created or bound.
    """

    chunks_hold_whole_frames = True  # a datagram carries whole frames (send_frames never splits one)

    def __init__(
        self,
        local: Address = ("127.0.0.1", 0),
        remote: Address | None = None,
        *,
        receivers: Iterable[int] | None = None,
        max_datagram: int = DEFAULT_MAX_DATAGRAM,
        receive_buffer: int | None = None,
    ) -> None:
        if max_datagram < MAX_ENCODED_SIZE:
            raise ValueError(f"max_datagram {max_datagram} is below the largest frame ({MAX_ENCODED_SIZE} bytes)")
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if receive_buffer is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
            sock.bind(local)
        except OSError as error:
            sock.close()  # never leave a half-configured socket behind
            raise TransportInitError(f"cannot bind UDP socket to {local[0]}:{local[1]}: {error}") from error
        self._sock = sock
        self._remote = remote
        self._last_peer: Address | None = None
        try:
            super().__init__(receivers, max_send_bytes=max_datagram)
        except BaseException:
            sock.close()
            raise

    @property
    def local_address(self) -> Address:
        """The bound (host, port), with the port the system chose for port 0."""
        host, port = self._sock.getsockname()[:2]
        return host, port

    @property
    def remote(self) -> Address | None:
        """Where frames go: the configured remote, else the last peer heard from (``None`` before any)."""
        return self._remote or self._last_peer

    def fileno(self) -> int:
        """The socket's descriptor (readable when a datagram waits)."""
        return self._sock.fileno()

    def _recv_bytes(self, timeout: float | None) -> tuple[bytes, Hashable] | None:
        try:
            try:
                data, peer = self._sock.recvfrom(_RECV_SIZE)
            except BlockingIOError:
                if timeout is not None and timeout <= 0.0:
                    return None
                readable, _, _ = select.select([self._sock], [], [], timeout)
                if not readable:
                    return None
                data, peer = self._sock.recvfrom(_RECV_SIZE)
        except BlockingIOError:
            return None  # select said readable but the datagram is gone (e.g. dropped for a bad checksum)
        except (OSError, ValueError) as error:  # ValueError: select on a closed socket
            raise TransportOperationError(f"UDP receive on {self._describe()} failed: {error}") from error
        self._last_peer = peer[:2]
        return data, peer

    def _send_bytes(self, data: bytes) -> None:
        target = self._remote or self._last_peer
        if target is None:
            raise TransportOperationError("UdpTransport has no remote and has heard from no peer yet")
        try:
            self._sock.sendto(data, target)
        except BlockingIOError as error:
            raise TransportOperationError(f"UDP send buffer full, datagram to {target} dropped") from error
        except OSError as error:
            raise TransportOperationError(f"UDP send to {target[0]}:{target[1]} failed: {error}") from error

    def _close(self) -> None:
        self._sock.close()

    def _describe(self) -> str:
        try:
            host, port = self.local_address
        except OSError:
            return "closed socket"
        remote = self.remote
        return f"{host}:{port} -> {remote[0]}:{remote[1]}" if remote else f"{host}:{port}"
