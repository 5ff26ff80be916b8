"""The transport interface: byte-level backends under one frame-level API, in the spirit of python-can's BusABC.

The base class owns what every link needs: the receive timeout loop, one NDLCom decoder per incoming byte stream,
receiver filtering, statistics, the lifecycle (idempotent ``shutdown``, context manager, ``__del__`` safety net)
and the error classes by phase. A backend implements only ``_recv_bytes`` and ``_send_bytes`` (and ``_close``).
"""

from __future__ import annotations

import contextlib
import logging
import time
from abc import ABC, abstractmethod
from collections.abc import Hashable, Iterable
from typing import NamedTuple, Self

from rh5_bringup.hardware.ndlcom.codec import BROADCAST, ESCAPE, FLAG, DecoderStats, Frame, FrameDecoder, LinkCounters

__all__ = [
    "Transport",
    "TransportError",
    "TransportInitError",
    "TransportOperationError",
    "TransportStats",
    "TransportTimeoutError",
]

LOG = logging.getLogger(__name__)

MAX_DRAIN_READS = 256
"""After the first frames arrive, ``recv`` reads at most this many more already-waiting chunks."""


class TransportError(Exception):
    """Base of the transport errors."""


class TransportInitError(TransportError):
    """The link could not be opened (bad address, port in use, no such CAN interface, missing package)."""


class TransportOperationError(TransportError):
    """Sending or receiving failed on an open link, or the link is already shut down."""


class TransportTimeoutError(TransportError, TimeoutError):
    """Fewer frames arrived than asked for before the timeout; ``frames`` holds those that did."""

    def __init__(self, message: str, frames: list[Frame] | None = None) -> None:
        super().__init__(message)
        self.frames: list[Frame] = frames or []


class TransportStats(NamedTuple):
    """A snapshot of a transport's counters."""

    sent_frames: int
    sent_bytes: int
    sent_chunks: int
    """Calls to ``_send_bytes`` (UDP datagrams; for CAN, NDLCom frames)."""
    received_bytes: int
    received_chunks: int
    """Chunks ``_recv_bytes`` returned (UDP datagrams, CAN frames)."""
    filtered_frames: int
    """Good frames dropped because they were addressed to someone else."""
    foreign_chunks: int
    """Chunks the backend ignored as not ours (e.g. CAN ids outside the NDLCom range)."""
    decoder: DecoderStats
    superseded_chunks: int = 0
    """Chunks ``recv_newest`` skipped undecoded because a newer burst from the same peer was waiting."""


def _first_frame_key(data: bytes) -> tuple[int, int] | None:
    """(receiver, sender) of the first frame of a chunk that starts with a flag and two unescaped bytes."""
    if len(data) < 3 or data[0] != FLAG or ESCAPE in (data[1], data[2]):
        return None
    return data[1], data[2]


class Transport(ABC):
    """A bidirectional NDLCom link.

    :param receivers: deliver only frames addressed to one of these ids (and broadcast); ``None`` delivers all.
    :param max_send_bytes: the most bytes one ``_send_bytes`` call may carry when ``send_frames`` packs several
        frames; ``None`` sends each frame on its own.

    Receiving is for one thread at a time; sending from another thread is safe for the backends here (the socket
    or python-can bus serialises it) but the send counters are then approximate.
    """

    _is_shutdown: bool = True
    """Class default: a constructor that failed before ``Transport.__init__`` leaves nothing to shut down."""
    chunks_hold_whole_frames: bool = False
    """Whether every chunk carries whole frames (UDP datagrams do; CAN frames carry pieces of one)."""

    def __init__(self, receivers: Iterable[int] | None = None, max_send_bytes: int | None = None) -> None:
        self.max_send_bytes = max_send_bytes
        """``send_frames`` packs frames into one ``_send_bytes`` call up to this size; ``None``: one per call."""
        self._accept: list[bool] | None = None
        if receivers is not None:
            self._accept = [False] * 256
            for receiver in receivers:
                if not 0 <= receiver <= BROADCAST:
                    raise ValueError(f"receiver id {receiver!r} is outside 0..255")
                self._accept[receiver] = True
            self._accept[BROADCAST] = True
        self._counters = LinkCounters()
        self._decoders: dict[Hashable, FrameDecoder] = {}
        self._sent_frames = self._sent_bytes = self._sent_chunks = 0
        self._received_bytes = self._received_chunks = self._filtered = 0
        self._foreign_chunks = 0
        self._superseded = 0
        self._is_shutdown = False

    # ----------------------------------------------------------------------------------------- backend hooks

    @abstractmethod
    def _recv_bytes(self, timeout: float | None) -> tuple[bytes, Hashable] | None:
        """Wait up to ``timeout`` s (``None``: forever, 0: poll) for one chunk of bytes.

        :returns: ``(data, stream)`` where ``stream`` names the byte stream the chunk continues (the peer, the CAN
            id), or ``None`` if nothing arrived in time. ``data`` may be empty (something arrived that was not ours).
        :raises TransportOperationError: the link failed.
        """

    @abstractmethod
    def _send_bytes(self, data: bytes) -> None:
        """Send encoded NDLCom bytes (one or more whole frames).

        :raises TransportOperationError: the link failed or the data cannot be sent.
        """

    def _close(self) -> None:  # noqa: B027 (optional hook, empty by default)
        """Release the backend's resources; called exactly once, by ``shutdown``."""

    def fileno(self) -> int:
        """A file descriptor that becomes readable when data arrives (for select); optional."""
        raise NotImplementedError(f"{type(self).__name__} has no file descriptor")

    # ----------------------------------------------------------------------------------------- receiving

    def recv(self, timeout: float | None = None) -> list[Frame]:
        """Wait up to ``timeout`` s for frames; return the first batch plus whatever else is already waiting.

        ``timeout=0`` polls, ``None`` waits forever. Returns ``[]`` on timeout (like python-can's ``recv``
        returning None); frames addressed to others are dropped when ``receivers`` was given.
        """
        self._check_open()
        deadline = None if timeout is None else time.monotonic() + timeout
        remaining = timeout
        late_polls = 0
        while True:
            chunk = self._recv_bytes(remaining)
            if chunk is None:
                return []
            frames = self._decode(chunk)
            if frames:
                break
            if deadline is not None:
                remaining = max(0.0, deadline - time.monotonic())
                if remaining == 0.0:
                    late_polls += 1  # past the deadline: only drain what is already waiting, boundedly
                    if late_polls > MAX_DRAIN_READS:
                        return []
        for _ in range(MAX_DRAIN_READS):
            chunk = self._recv_bytes(0.0)
            if chunk is None:
                break
            frames += self._decode(chunk)
        return frames

    def recv_newest(self, timeout: float | None = None) -> list[Frame]:
        """Like ``recv``, but of the chunks already waiting only the newest burst of each peer is decoded.

        For a receiver slower than its peer (a simulation behind real time): every command burst supersedes
        the one before, so decoding the stale ones only costs time. Going from the newest chunk back, chunks
        are kept until one starts with a (receiver, sender) pair a kept one already has (an older burst);
        the rest are counted in ``superseded_chunks`` and their frame-counter gap is not counted as loss.
        Links whose chunks carry pieces of frames (CAN) fall back to ``recv``.
        """
        if not self.chunks_hold_whole_frames:
            return self.recv(timeout)
        self._check_open()
        first = self._recv_bytes(timeout)
        if first is None:
            return []
        chunks = [first]
        for _ in range(MAX_DRAIN_READS):
            chunk = self._recv_bytes(0.0)
            if chunk is None:
                break
            chunks.append(chunk)
        kept: list[tuple[bytes, Hashable]] = []
        seen: set[tuple[Hashable, int, int]] = set()
        for data, stream in reversed(chunks):
            key = _first_frame_key(data)
            if key is not None and (stream, *key) in seen:
                break
            if key is not None:
                seen.add((stream, *key))
            kept.append((data, stream))
        skipped = len(chunks) - len(kept)
        self._superseded += skipped
        frames: list[Frame] = []
        for k, chunk in enumerate(reversed(kept)):
            frames += self._decode(chunk, resync=skipped > 0 and k == 0)
        return frames

    def recv_frames(self, count: int, timeout: float) -> list[Frame]:
        """Collect at least ``count`` frames within ``timeout`` s.

        :raises TransportTimeoutError: fewer arrived; the exception's ``frames`` holds those that did.
        """
        deadline = time.monotonic() + timeout
        frames: list[Frame] = []
        while len(frames) < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise TransportTimeoutError(
                    f"{type(self).__name__}: {len(frames)} of {count} frames within {timeout} s", frames
                )
            frames += self.recv(remaining)
        return frames

    def _decode(self, chunk: tuple[bytes, Hashable], *, resync: bool = False) -> list[Frame]:
        data, stream = chunk
        self._received_chunks += 1
        if not data:
            self._foreign_chunks += 1
            return []
        self._received_bytes += len(data)
        decoder = self._decoders.get(stream)
        if decoder is None:
            decoder = self._decoders[stream] = FrameDecoder(self._counters)
        frames = decoder.feed(data, resync_counters=resync)
        accept = self._accept
        if accept is None or not frames:
            return frames
        kept = [f for f in frames if accept[f.receiver]]
        self._filtered += len(frames) - len(kept)
        return kept

    # ----------------------------------------------------------------------------------------- sending

    def send_frame(self, frame: bytes) -> None:
        """Send one encoded frame (``encode_frame``'s output).

        :raises TransportOperationError: the link failed or is shut down.
        """
        self._check_open()
        self._send_bytes(frame)
        self._sent_frames += 1
        self._sent_bytes += len(frame)
        self._sent_chunks += 1

    def send_frames(self, frames: Iterable[bytes]) -> None:
        """Send several encoded frames, packed into as few ``_send_bytes`` calls as ``max_send_bytes`` allows."""
        self._check_open()
        limit = self.max_send_bytes
        if limit is None:
            for frame in frames:
                self.send_frame(frame)
            return
        frames = frames if isinstance(frames, list) else list(frames)
        total = sum(map(len, frames))
        if total <= limit:  # the common case, a cycle's frames in one datagram
            self._send_batch(frames, total)
            return
        batch: list[bytes] = []
        size = 0
        for frame in frames:
            if batch and size + len(frame) > limit:
                self._send_batch(batch, size)
                batch, size = [], 0
            batch.append(frame)
            size += len(frame)
        if batch:
            self._send_batch(batch, size)

    def _send_batch(self, batch: list[bytes], size: int) -> None:
        self._send_bytes(b"".join(batch))
        self._sent_frames += len(batch)
        self._sent_bytes += size
        self._sent_chunks += 1

    # ----------------------------------------------------------------------------------------- state

    def stats(self) -> TransportStats:
        """A snapshot of the send/receive counters and the decoders' per-sender statistics."""
        return TransportStats(
            self._sent_frames,
            self._sent_bytes,
            self._sent_chunks,
            self._received_bytes,
            self._received_chunks,
            self._filtered,
            self._foreign_chunks,
            self._counters.snapshot(),
            self._superseded,
        )

    @property
    def is_shutdown(self) -> bool:
        """True once ``shutdown`` ran (or the constructor failed)."""
        return self._is_shutdown

    def _check_open(self) -> None:
        if self._is_shutdown:
            raise TransportOperationError(f"{type(self).__name__} is shut down")

    def shutdown(self) -> None:
        """Close the link. Safe to call any number of times; later calls do nothing."""
        if self._is_shutdown:
            return
        self._is_shutdown = True
        self._close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.shutdown()

    def __del__(self) -> None:
        if not self._is_shutdown:
            LOG.warning("%s was not properly shut down", type(self).__name__)
            # a subclass whose constructor failed halfway may lack the attributes _close needs
            with contextlib.suppress(AttributeError):
                self.shutdown()

    def __repr__(self) -> str:
        state = "shut down" if self._is_shutdown else "open"
        return f"<{type(self).__name__} {self._describe()} ({state})>"

    def _describe(self) -> str:
        return ""
