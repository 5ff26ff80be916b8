"""MCAP records as bytes (the format of https://mcap.dev/spec), and a scanner that stops at a cut-off record.

Only the records a rosbag2-style file uses: header, schema, channel, message (inside chunks), chunk,
message index, chunk index, statistics, metadata and its index, summary offsets, data end, footer.
Integers are little-endian; strings, byte arrays and maps carry a uint32 byte-length prefix; every
record is ``opcode (uint8) | content length (uint64) | content``.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Final, NamedTuple

from rh5_bringup.recording.compression import decompress

__all__ = [
    "MAGIC",
    "MESSAGE_FIXED_SIZE",
    "MESSAGE_PREFIX",
    "ChunkIndex",
    "ChunkView",
    "Opcode",
    "RawRecord",
    "Statistics",
    "channel_record",
    "chunk_record",
    "data_end_record",
    "header_record",
    "iter_chunk_messages",
    "iter_records",
    "message_index_record",
    "metadata_index_record",
    "metadata_record",
    "parse_channel",
    "parse_chunk",
    "parse_chunk_index",
    "parse_footer",
    "parse_metadata",
    "parse_schema",
    "parse_statistics",
    "schema_record",
    "summary_and_footer",
]

MAGIC: Final = b"\x89MCAP0\r\n"
"""Starts and ends every MCAP file."""


class Opcode(IntEnum):
    """Record opcodes of the MCAP specification."""

    HEADER = 0x01
    FOOTER = 0x02
    SCHEMA = 0x03
    CHANNEL = 0x04
    MESSAGE = 0x05
    CHUNK = 0x06
    MESSAGE_INDEX = 0x07
    CHUNK_INDEX = 0x08
    ATTACHMENT = 0x09
    ATTACHMENT_INDEX = 0x0A
    STATISTICS = 0x0B
    METADATA = 0x0C
    METADATA_INDEX = 0x0D
    SUMMARY_OFFSET = 0x0E
    DATA_END = 0x0F


_PREFIX: Final = struct.Struct("<BQ")
_U16: Final = struct.Struct("<H")
_U32: Final = struct.Struct("<I")
_U64: Final = struct.Struct("<Q")
MESSAGE_PREFIX: Final = struct.Struct("<BQHIQQ")
"""Opcode, length, channel id, sequence, log time, publish time: a message record up to its data."""
MESSAGE_FIXED_SIZE: Final = 22
"""Content bytes of a message record before its data (channel id, sequence, log and publish time)."""
_MESSAGE_FIELDS: Final = struct.Struct("<HIQQ")
_CHUNK_FIELDS: Final = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed CRC
_CHUNK_INDEX_HEAD: Final = struct.Struct("<QQQQ")  # start, end, chunk offset, chunk length
_STATISTICS_HEAD: Final = struct.Struct("<QHIIIIQQ")
_SUMMARY_OFFSET: Final = struct.Struct("<BQQ")
_FOOTER: Final = struct.Struct("<BQQQI")
_FOOTER_LENGTH: Final = 20  # summary start, summary offset start, summary CRC


def _string(text: str) -> bytes:
    raw = text.encode("utf-8")
    return _U32.pack(len(raw)) + raw


def _string_map(entries: Mapping[str, str]) -> bytes:
    body = b"".join(_string(key) + _string(value) for key, value in entries.items())
    return _U32.pack(len(body)) + body


def _record(opcode: Opcode, content: bytes) -> bytes:
    return _PREFIX.pack(opcode, len(content)) + content


def header_record(profile: str, library: str) -> bytes:
    """The header: the profile (``ros2`` for rosbag2) and the writing library."""
    return _record(Opcode.HEADER, _string(profile) + _string(library))


def schema_record(schema_id: int, name: str, encoding: str, data: bytes) -> bytes:
    """A schema (id >= 1): for ROS 2 the type name, ``ros2msg`` and the full message definition."""
    content = _U16.pack(schema_id) + _string(name) + _string(encoding) + _U32.pack(len(data)) + data
    return _record(Opcode.SCHEMA, content)


def channel_record(channel_id: int, schema_id: int, topic: str, encoding: str, metadata: Mapping[str, str]) -> bytes:
    """A channel: the topic, its message encoding (``cdr``) and string metadata (QoS, type hash)."""
    content = _U16.pack(channel_id) + _U16.pack(schema_id) + _string(topic) + _string(encoding) + _string_map(metadata)
    return _record(Opcode.CHANNEL, content)


def chunk_record(
    start_time: int,
    end_time: int,
    records_size: int,
    crc: int,
    stored: bytes | bytearray,
    *,
    compression: str = "",
) -> bytes:
    """A chunk of message records logged in [start_time, end_time]: ``records_size`` bytes with CRC ``crc``
    before compression, ``stored`` as written (the records themselves when ``compression`` is empty)."""
    head = _CHUNK_FIELDS.pack(start_time, end_time, records_size, crc) + _string(compression) + _U64.pack(len(stored))
    return _PREFIX.pack(Opcode.CHUNK, len(head) + len(stored)) + head + stored


def message_index_record(channel_id: int, entries: bytes) -> bytes:
    """The message index of one channel in one chunk; ``entries`` are packed (log time, offset) uint64 pairs."""
    return _record(Opcode.MESSAGE_INDEX, _U16.pack(channel_id) + _U32.pack(len(entries)) + entries)


def metadata_record(name: str, entries: Mapping[str, str]) -> bytes:
    """A named string map (rosbag2 writes ``rosbag2`` with its serialized metadata when it closes a bag)."""
    return _record(Opcode.METADATA, _string(name) + _string_map(entries))


def metadata_index_record(offset: int, length: int, name: str) -> bytes:
    """Where a metadata record lies in the file (summary section)."""
    return _record(Opcode.METADATA_INDEX, _U64.pack(offset) + _U64.pack(length) + _string(name))


def data_end_record(data_crc: int = 0) -> bytes:
    """Ends the data section (CRC 0: not computed, as rosbag2's writer does by default)."""
    return _record(Opcode.DATA_END, _U32.pack(data_crc))


@dataclass(frozen=True)
class ChunkIndex:
    """Where one chunk lies and where its message indexes follow it (summary section)."""

    start_time: int
    end_time: int
    offset: int
    length: int
    message_index_offsets: Mapping[int, int]
    message_index_length: int
    records_size: int
    """Bytes of the chunk's message records, uncompressed."""
    compression: str = ""
    stored_size: int | None = None
    """Bytes of the records as stored in the chunk (compressed); None: uncompressed, ``records_size``."""

    def encode(self) -> bytes:
        """The chunk index record."""
        offsets = b"".join(_U16.pack(cid) + _U64.pack(off) for cid, off in self.message_index_offsets.items())
        content = (
            _CHUNK_INDEX_HEAD.pack(self.start_time, self.end_time, self.offset, self.length)
            + _U32.pack(len(offsets))
            + offsets
            + _U64.pack(self.message_index_length)
            + _string(self.compression)
            + _U64.pack(self.records_size if self.stored_size is None else self.stored_size)
            + _U64.pack(self.records_size)
        )
        return _record(Opcode.CHUNK_INDEX, content)


@dataclass
class Statistics:
    """Counts and the log-time range of the whole file (summary section), kept up to date while writing."""

    schema_count: int = 0
    channel_count: int = 0
    metadata_count: int = 0
    chunk_count: int = 0
    start_time: int = 0
    end_time: int = 0
    channel_message_counts: dict[int, int] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        """Messages in the file."""
        return sum(self.channel_message_counts.values())

    def add_chunk(self, start_time: int, end_time: int, counts: Mapping[int, int]) -> None:
        """Account for one more chunk with ``counts`` messages per channel logged in [start_time, end_time]."""
        if not counts:
            return
        if self.message_count == 0:
            self.start_time, self.end_time = start_time, end_time
        else:
            self.start_time, self.end_time = min(self.start_time, start_time), max(self.end_time, end_time)
        for cid, count in counts.items():
            self.channel_message_counts[cid] = self.channel_message_counts.get(cid, 0) + count
        self.chunk_count += 1

    def encode(self) -> bytes:
        """The statistics record (no attachments are ever written)."""
        counts = b"".join(_U16.pack(cid) + _U64.pack(n) for cid, n in sorted(self.channel_message_counts.items()))
        head = _STATISTICS_HEAD.pack(
            self.message_count,
            self.schema_count,
            self.channel_count,
            0,
            self.metadata_count,
            self.chunk_count,
            self.start_time,
            self.end_time,
        )
        return _record(Opcode.STATISTICS, head + _U32.pack(len(counts)) + counts)


def summary_and_footer(
    summary_start: int,
    *,
    schemas: Iterable[bytes],
    channels: Iterable[bytes],
    statistics: Statistics,
    chunk_indexes: Iterable[ChunkIndex],
    metadata_indexes: Iterable[bytes],
) -> bytes:
    """Everything after the data end record: the summary groups, their offsets, the footer and the end magic.

    ``summary_start`` is the file offset at which these bytes will be written; ``schemas`` and
    ``channels`` are the encoded records of the data section, repeated as rosbag2's writer does.
    """
    groups = [
        (Opcode.SCHEMA, b"".join(schemas)),
        (Opcode.CHANNEL, b"".join(channels)),
        (Opcode.STATISTICS, statistics.encode()),
        (Opcode.CHUNK_INDEX, b"".join(index.encode() for index in chunk_indexes)),
        (Opcode.METADATA_INDEX, b"".join(metadata_indexes)),
    ]
    body, offsets, position = [], [], summary_start
    for opcode, data in groups:
        if data:
            body.append(data)
            offsets.append(_record(Opcode.SUMMARY_OFFSET, _SUMMARY_OFFSET.pack(opcode, position, len(data))))
            position += len(data)
    summary_offset_start = position
    footer_head = _FOOTER.pack(Opcode.FOOTER, _FOOTER_LENGTH, summary_start, summary_offset_start, 0)[:-4]
    summary = b"".join(body) + b"".join(offsets)
    crc = zlib.crc32(footer_head, zlib.crc32(summary))
    return summary + footer_head + _U32.pack(crc) + MAGIC


# --- reading (recovery of a file whose writer was killed) ----------------------------------------------------


class RawRecord(NamedTuple):
    """One record found by :func:`iter_records`: its opcode, file offset, total length and content."""

    opcode: int
    offset: int
    length: int
    content: memoryview


def iter_records(data: memoryview, start: int = len(MAGIC)) -> Iterator[RawRecord]:
    """Records of ``data`` from ``start`` on, in file order, up to the first one that is cut off."""
    position, end = start, len(data)
    while position + _PREFIX.size <= end:
        opcode, length = _PREFIX.unpack_from(data, position)
        content_start = position + _PREFIX.size
        if length > end - content_start:
            return
        yield RawRecord(opcode, position, _PREFIX.size + length, data[content_start : content_start + length])
        position = content_start + length


def _read_string(content: memoryview, position: int) -> tuple[str, int]:
    (size,) = _U32.unpack_from(content, position)
    start = position + _U32.size
    return bytes(content[start : start + size]).decode("utf-8"), start + size


def _read_string_map(content: memoryview, position: int) -> tuple[dict[str, str], int]:
    (size,) = _U32.unpack_from(content, position)
    position += _U32.size
    end, entries = position + size, {}
    while position < end:
        key, position = _read_string(content, position)
        entries[key], position = _read_string(content, position)
    return entries, end


def parse_schema(content: memoryview) -> tuple[int, str]:
    """(id, name) of a schema record's content."""
    (schema_id,) = _U16.unpack_from(content, 0)
    name, _ = _read_string(content, _U16.size)
    return schema_id, name


def parse_channel(content: memoryview) -> tuple[int, int, str, str, dict[str, str]]:
    """(id, schema id, topic, message encoding, metadata) of a channel record's content."""
    channel_id, schema_id = struct.unpack_from("<HH", content, 0)
    topic, position = _read_string(content, 4)
    encoding, position = _read_string(content, position)
    metadata, _ = _read_string_map(content, position)
    return channel_id, schema_id, topic, encoding, metadata


def parse_metadata(content: memoryview) -> tuple[str, dict[str, str]]:
    """(name, entries) of a metadata record's content."""
    name, position = _read_string(content, 0)
    entries, _ = _read_string_map(content, position)
    return name, entries


class ChunkView(NamedTuple):
    """The fields of a chunk record and a view of its records, decompressed."""

    start_time: int
    end_time: int
    crc: int
    compression: str
    records: memoryview
    stored_size: int
    """Bytes of the records as stored (compressed)."""


def parse_chunk(content: memoryview) -> ChunkView:
    """The chunk record's fields and decompressed records; ValueError when they are cut short, do not
    decompress or fail their CRC, LookupError for a compression other than zstd or none."""
    start, end, size, crc = _CHUNK_FIELDS.unpack_from(content, 0)
    compression, position = _read_string(content, _CHUNK_FIELDS.size)
    (stored_size,) = _U64.unpack_from(content, position)
    stored = content[position + _U64.size : position + _U64.size + stored_size]
    if len(stored) != stored_size:
        msg = f"chunk records cut short: {len(stored)} of {stored_size} bytes"
        raise ValueError(msg)
    records = memoryview(decompress(compression, stored, size))
    if len(records) != size or (crc and zlib.crc32(records) != crc):
        msg = "chunk records do not match their size or CRC"
        raise ValueError(msg)
    return ChunkView(start, end, crc, compression, records, stored_size)


def iter_chunk_messages(records: memoryview) -> Iterator[tuple[int, int, int]]:
    """(channel id, log time, offset in the chunk) of every message record of a chunk's (decompressed) records."""
    for record in iter_records(records, 0):
        if record.opcode == Opcode.MESSAGE:
            channel_id, _, log_time, _ = _MESSAGE_FIELDS.unpack_from(record.content, 0)
            yield channel_id, log_time, record.offset


def parse_statistics(content: memoryview) -> Statistics:
    """The statistics record's content (the attachment count, always 0 here, is not kept)."""
    (message_count, schemas, channels, _, metadata, chunks, start, end) = _STATISTICS_HEAD.unpack_from(content, 0)
    (size,) = _U32.unpack_from(content, _STATISTICS_HEAD.size)
    position = _STATISTICS_HEAD.size + _U32.size
    counts = {}
    for offset in range(position, position + size, _U16.size + _U64.size):
        (channel_id,) = _U16.unpack_from(content, offset)
        (counts[channel_id],) = _U64.unpack_from(content, offset + _U16.size)
    statistics = Statistics(schemas, channels, metadata, chunks, start, end, counts)
    if statistics.message_count != message_count:  # a writer may count without per-channel counts
        statistics.channel_message_counts = counts or {0: message_count}
    return statistics


def parse_chunk_index(content: memoryview) -> ChunkIndex:
    """The chunk index record's content."""
    start, end, offset, length = _CHUNK_INDEX_HEAD.unpack_from(content, 0)
    (size,) = _U32.unpack_from(content, _CHUNK_INDEX_HEAD.size)
    position = _CHUNK_INDEX_HEAD.size + _U32.size
    offsets = {}
    for entry in range(position, position + size, _U16.size + _U64.size):
        (channel_id,) = _U16.unpack_from(content, entry)
        (offsets[channel_id],) = _U64.unpack_from(content, entry + _U16.size)
    position += size
    (index_length,) = _U64.unpack_from(content, position)
    compression, position = _read_string(content, position + _U64.size)
    stored, records = struct.unpack_from("<QQ", content, position)
    return ChunkIndex(start, end, offset, length, offsets, index_length, records, compression, stored)


def parse_footer(data: memoryview) -> int | None:
    """Where the summary section of a complete file starts (None: the file has no summary)."""
    content_start = len(data) - len(MAGIC) - _FOOTER_LENGTH
    (summary_start,) = _U64.unpack_from(data, content_start)
    return summary_start or None
