"""A streaming MCAP writer whose file is readable up to its last chunk at every moment.

Schemas and channels go to the file as they are added; messages collect in a chunk that is
compressed (zstd by default, compression.py) and written, with its message indexes, in one ``write``
to an unbuffered file when its records reach ``chunk_size`` or when the owner closes it (the bag
writer does so by age). A process killed at any
point thus leaves a file whose records up to the last complete chunk are intact (recovery.py ends
it properly). ``finish`` adds the summary rosbag2's writer produces: schemas, channels, statistics,
chunk indexes, metadata indexes and summary offsets, then the footer.
"""

from __future__ import annotations

import zlib
from array import array
from pathlib import Path
from typing import BinaryIO, Final

import numpy as np

from rh5_bringup.recording.compression import DEFAULT_COMPRESSION, DEFAULT_LEVEL, ChunkCompressor
from rh5_bringup.recording.errors import BagWriterError
from rh5_bringup.recording.mcap_format import (
    MAGIC,
    MESSAGE_FIXED_SIZE,
    MESSAGE_PREFIX,
    ChunkIndex,
    Opcode,
    Statistics,
    channel_record,
    chunk_record,
    data_end_record,
    header_record,
    message_index_record,
    metadata_index_record,
    metadata_record,
    schema_record,
    summary_and_footer,
)

__all__ = ["DEFAULT_CHUNK_SIZE", "McapStreamWriter", "write_all"]

DEFAULT_CHUNK_SIZE: Final = 768 * 1024
"""Bytes of message records per chunk: the default of the MCAP C++ writer that rosbag2 uses."""
_UINT32: Final = 0xFFFFFFFF


def write_all(stream: BinaryIO, data: bytes | bytearray | memoryview) -> None:
    """Write every byte to an unbuffered file (a raw write may take only part of it)."""
    view = memoryview(data)
    while view:
        written = stream.write(view)
        if written is None:  # pragma: no cover (only non-blocking files return None)
            msg = "the file refused a write"
            raise BagWriterError(msg)
        view = view[written:]


class McapStreamWriter:
    """Writes one MCAP file: open, add schemas/channels, write messages, close chunks, finish (or abort)."""

    def __init__(
        self,
        path: Path,
        *,
        profile: str,
        library: str,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        compression: str = DEFAULT_COMPRESSION,
        compression_level: int = DEFAULT_LEVEL,
    ) -> None:
        if chunk_size <= 0:
            msg = f"chunk_size must be positive, got {chunk_size}"
            raise ValueError(msg)
        self.path = Path(path)
        self.profile = profile
        self.library = library
        self.chunk_size = chunk_size
        self._compressor = ChunkCompressor(compression, compression_level)
        self.statistics = Statistics()
        self._file: BinaryIO | None = None
        self._finished = False
        self._position = 0
        self._schemas: list[bytes] = []
        self._channels: dict[int, bytes] = {}
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[bytes] = []
        self._reset_chunk()

    # --- lifecycle -------------------------------------------------------------------------------------------

    @property
    def position(self) -> int:
        """Bytes written to the file so far."""
        return self._position

    @property
    def compression(self) -> str:
        """The chunks' compression: ``zstd`` or ``""``."""
        return self._compressor.compression

    @property
    def is_open(self) -> bool:
        """Whether messages can be written."""
        return self._file is not None

    def open(self) -> None:
        """Create the file (never overwriting one) and write the magic and header."""
        if self._file is not None or self._finished:
            msg = f"{self.path}: already opened"
            raise BagWriterError(msg)
        try:
            self._file = open(self.path, "xb", buffering=0)  # noqa: SIM115 (held until finish/abort)
        except FileExistsError:
            msg = f"{self.path} exists already, not overwriting it"
            raise BagWriterError(msg) from None
        self._append(MAGIC + header_record(self.profile, self.library))

    def finish(self) -> None:
        """Write the open chunk, the data end, the summary and the footer, and close the file."""
        self._require_open()
        self.close_chunk()
        self._append(data_end_record())
        channels = [self._channels[cid] for cid in sorted(self._channels)]
        summary = summary_and_footer(
            self._position,
            schemas=self._schemas,
            channels=channels,
            statistics=self.statistics,
            chunk_indexes=self._chunk_indexes,
            metadata_indexes=self._metadata_indexes,
        )
        self._append(summary)
        self._close_file()

    def abort(self) -> None:
        """Close the file as it is (readable up to its last chunk, see recovery.py). Idempotent."""
        if self._file is not None:
            self._close_file()

    # --- content ---------------------------------------------------------------------------------------------

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        """Write a schema record; returns its id (1, 2, ...)."""
        self._require_open()
        schema_id = len(self._schemas) + 1
        record = schema_record(schema_id, name, encoding, data)
        self._append(record)
        self._schemas.append(record)
        self.statistics.schema_count += 1
        return schema_id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        """Write a channel record; returns its id (1, 2, ...)."""
        self._require_open()
        if not 1 <= schema_id <= len(self._schemas):
            msg = f"channel {topic!r}: unknown schema id {schema_id}"
            raise BagWriterError(msg)
        channel_id = len(self._channels) + 1
        record = channel_record(channel_id, schema_id, topic, message_encoding, metadata)
        self._append(record)
        self._channels[channel_id] = record
        self.statistics.channel_count += 1
        return channel_id

    def write_message(
        self, channel_id: int, log_time: int, publish_time: int, data: bytes | memoryview, sequence: int = 0
    ) -> None:
        """Add one message to the open chunk (which is written out once it holds ``chunk_size`` bytes)."""
        if self._file is None or channel_id not in self._channels:
            self._require_open()
            msg = f"unknown channel id {channel_id}"
            raise BagWriterError(msg)
        chunk = self._chunk
        offset = len(chunk)
        chunk += MESSAGE_PREFIX.pack(
            Opcode.MESSAGE, MESSAGE_FIXED_SIZE + len(data), channel_id, sequence & _UINT32, log_time, publish_time
        )
        chunk += data
        entries = self._index.get(channel_id)
        if entries is None:
            entries = self._index[channel_id] = array("Q")
        elif log_time < entries[-2]:
            self._unsorted.add(channel_id)
        entries.append(log_time)
        entries.append(offset)
        if self._chunk_messages == 0:
            self._chunk_start = self._chunk_end = log_time
        elif log_time < self._chunk_start:
            self._chunk_start = log_time
        elif log_time > self._chunk_end:
            self._chunk_end = log_time
        self._chunk_messages += 1
        if len(chunk) >= self.chunk_size:
            self.close_chunk()

    @property
    def pending_messages(self) -> int:
        """Messages in the open chunk (not in the file yet)."""
        return self._chunk_messages

    def close_chunk(self) -> bool:
        """Write the open chunk and its message indexes to the file in one write; False if it was empty."""
        if self._chunk_messages == 0:
            return False
        self._require_open()
        records = self._chunk
        compression = self._compressor.compression
        stored = self._compressor.compress(records)
        crc = zlib.crc32(records)
        chunk = chunk_record(self._chunk_start, self._chunk_end, len(records), crc, stored, compression=compression)
        chunk_offset = self._position
        index_offsets: dict[int, int] = {}
        indexes: list[bytes] = []
        counts: dict[int, int] = {}
        position = chunk_offset + len(chunk)
        for channel_id in sorted(self._index):
            entries = self._index_bytes(channel_id)
            record = message_index_record(channel_id, entries)
            index_offsets[channel_id] = position
            counts[channel_id] = len(entries) // 16
            indexes.append(record)
            position += len(record)
        self._append(chunk + b"".join(indexes))
        self._chunk_indexes.append(
            ChunkIndex(
                self._chunk_start,
                self._chunk_end,
                chunk_offset,
                len(chunk),
                index_offsets,
                position - chunk_offset - len(chunk),
                len(records),
                compression,
                len(stored),
            )
        )
        self.statistics.add_chunk(self._chunk_start, self._chunk_end, counts)
        self._reset_chunk()
        return True

    def add_metadata(self, name: str, entries: dict[str, str]) -> None:
        """Write a metadata record (outside chunks) and remember its index for the summary."""
        self._require_open()
        self.close_chunk()
        record = metadata_record(name, entries)
        self._metadata_indexes.append(metadata_index_record(self._position, len(record), name))
        self._append(record)
        self.statistics.metadata_count += 1

    # --- internals -------------------------------------------------------------------------------------------

    def _index_bytes(self, channel_id: int) -> bytes:
        """Packed little-endian (log time, offset) pairs of one channel, sorted by log time."""
        pairs = np.frombuffer(self._index[channel_id], dtype=np.uint64).reshape(-1, 2)
        if channel_id in self._unsorted:
            pairs = pairs[np.argsort(pairs[:, 0], kind="stable")]
        return np.ascontiguousarray(pairs, dtype="<u8").tobytes()

    def _reset_chunk(self) -> None:
        self._chunk = bytearray()
        self._index: dict[int, array[int]] = {}
        self._unsorted: set[int] = set()
        self._chunk_messages = 0
        self._chunk_start = 0
        self._chunk_end = 0

    def _append(self, data: bytes | bytearray) -> None:
        assert self._file is not None
        write_all(self._file, data)
        self._position += len(data)

    def _require_open(self) -> None:
        if self._file is None:
            state = "finished" if self._finished else "not opened"
            msg = f"{self.path}: the MCAP file is {state}"
            raise BagWriterError(msg)

    def _close_file(self) -> None:
        assert self._file is not None
        file, self._file = self._file, None
        self._finished = True
        file.close()
