"""Complete a bag whose recorder was killed: keep every whole record, add the summary, rewrite metadata.yaml.

Every split file of the bag is checked; only those without a footer (normally the last) are changed.

A killed :class:`~rh5_bringup.recording.bag.BagWriter` leaves an MCAP file that ends inside (or
right after) a chunk, without data end, summary or footer; streaming readers read it up to the
cut, rosbags' reader refuses it. :func:`recover_bag` cuts the file after its last whole record,
appends what ``close`` would have written (the ``rosbag2`` metadata record, data end, summary with
statistics and chunk indexes, footer) and rewrites metadata.yaml from the file's own channels, in
the spirit of ``ros2 bag reindex``. A complete file is left untouched.
"""

from __future__ import annotations

import mmap
import os
import struct
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from rh5_bringup.recording.bag import bag_files, mcap_file_of
from rh5_bringup.recording.errors import BagRecoveryError
from rh5_bringup.recording.mcap_format import (
    MAGIC,
    ChunkIndex,
    Opcode,
    Statistics,
    data_end_record,
    iter_chunk_messages,
    iter_records,
    message_index_record,
    metadata_index_record,
    metadata_record,
    parse_channel,
    parse_chunk,
    parse_metadata,
    parse_schema,
    summary_and_footer,
)
from rh5_bringup.recording.metadata import (
    METADATA_FILE,
    BagTopic,
    FileSpan,
    OfferedQos,
    bag_metadata,
    dump_metadata,
    write_metadata_file,
)

__all__ = ["FileScan", "RecoveryResult", "is_complete", "recover_bag", "scan_records"]

_FOOTER_RECORD_SIZE = 1 + 8 + 20  # opcode, length, footer content
_PAIR = struct.Struct("<QQ")


@dataclass(frozen=True)
class RecoveryResult:
    """What :func:`recover_bag` found and did."""

    bag: Path
    recovered: bool
    """False when the file was complete already (nothing changed)."""
    message_count: int
    chunk_count: int
    discarded_bytes: int
    """Bytes after the last whole record (the chunk being written when the recorder died)."""
    counts: dict[str, int] = field(default_factory=dict)


def is_complete(mcap_path: Path) -> bool:
    """Whether an MCAP file ends with a footer and the closing magic."""
    size = mcap_path.stat().st_size
    if size < 2 * len(MAGIC) + _FOOTER_RECORD_SIZE:
        return False
    with mcap_path.open("rb") as stream:
        stream.seek(size - len(MAGIC) - _FOOTER_RECORD_SIZE)
        tail = stream.read()
    return tail[0] == Opcode.FOOTER and tail.endswith(MAGIC)


@dataclass
class FileScan:
    """The whole records of a (possibly cut) file: what its summary would say."""

    end: int = 0
    schemas: list[bytes] = field(default_factory=list)
    schema_names: dict[int, str] = field(default_factory=dict)
    channels: dict[int, bytes] = field(default_factory=dict)
    channel_info: dict[int, tuple[int, str, dict[str, str]]] = field(default_factory=dict)
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    metadata_indexes: list[bytes] = field(default_factory=list)
    statistics: Statistics = field(default_factory=Statistics)
    tail: bytes = b""
    """Message indexes rebuilt for the last chunk (written at ``end``) when the cut took some of its own."""

    @property
    def append_at(self) -> int:
        """Where the records that complete the file go."""
        return self.end + len(self.tail)


def scan_records(data: memoryview) -> FileScan:
    """Read every whole record of an MCAP file up to a cut, decompressing and indexing each whole chunk."""
    if bytes(data[: len(MAGIC)]) != MAGIC:
        msg = "not an MCAP file (no magic)"
        raise BagRecoveryError(msg)
    scan = FileScan(end=len(MAGIC))
    records = iter_records(data)
    first = next(records, None)
    if first is None or first.opcode != Opcode.HEADER:
        msg = "no MCAP header record"
        raise BagRecoveryError(msg)
    scan.end = first.offset + first.length
    index_owner: ChunkIndex | None = None
    entries: dict[int, list[tuple[int, int]]] = {}
    for record in records:
        content = record.content
        if record.opcode == Opcode.SCHEMA:
            schema_id, name = parse_schema(content)
            scan.schemas.append(bytes(data[record.offset : record.offset + record.length]))
            scan.schema_names[schema_id] = name
            scan.statistics.schema_count += 1
        elif record.opcode == Opcode.CHANNEL:
            channel_id, schema_id, topic, _, metadata = parse_channel(content)
            scan.channels[channel_id] = bytes(data[record.offset : record.offset + record.length])
            scan.channel_info[channel_id] = (schema_id, topic, metadata)
            scan.statistics.channel_count += 1
        elif record.opcode == Opcode.CHUNK:
            try:
                chunk = parse_chunk(content)
            except LookupError as err:
                raise BagRecoveryError(str(err)) from None
            except ValueError:
                break  # torn chunk: the file ends before it
            entries = {}
            for channel_id, log_time, offset in iter_chunk_messages(chunk.records):
                entries.setdefault(channel_id, []).append((log_time, offset))
            counts = {cid: len(e) for cid, e in entries.items()}
            scan.statistics.add_chunk(chunk.start_time, chunk.end_time, counts)
            index_owner = ChunkIndex(
                chunk.start_time,
                chunk.end_time,
                record.offset,
                record.length,
                {},
                0,
                len(chunk.records),
                chunk.compression,
                chunk.stored_size,
            )
            scan.chunk_indexes.append(index_owner)
        elif record.opcode == Opcode.MESSAGE_INDEX:
            if index_owner is not None:  # the indexes of the chunk just before
                offsets = {**index_owner.message_index_offsets, int.from_bytes(content[:2], "little"): record.offset}
                length = record.offset + record.length - min(offsets.values())
                index_owner = replace(index_owner, message_index_offsets=offsets, message_index_length=length)
                scan.chunk_indexes[-1] = index_owner
        elif record.opcode == Opcode.METADATA:
            name, _ = parse_metadata(content)
            scan.metadata_indexes.append(metadata_index_record(record.offset, record.length, name))
            scan.statistics.metadata_count += 1
        elif record.opcode in (Opcode.DATA_END, Opcode.FOOTER):
            break  # the summary was being written: the data section before it is whole
        if record.opcode not in (Opcode.CHUNK, Opcode.MESSAGE_INDEX):
            index_owner = None
        scan.end = record.offset + record.length
    if index_owner is not None and set(index_owner.message_index_offsets) != set(entries):
        _rebuild_last_indexes(scan, index_owner, entries)
    return scan


def _rebuild_last_indexes(scan: FileScan, chunk: ChunkIndex, entries: dict[int, list[tuple[int, int]]]) -> None:
    """Drop the last chunk's partial message indexes and append whole ones (readers such as rosbags need them)."""
    scan.end = chunk.offset + chunk.length
    records, offsets, position = [], {}, scan.end
    for channel_id in sorted(entries):
        packed = b"".join(_PAIR.pack(t, off) for t, off in sorted(entries[channel_id]))
        record = message_index_record(channel_id, packed)
        offsets[channel_id] = position
        records.append(record)
        position += len(record)
    scan.tail = b"".join(records)
    scan.chunk_indexes[-1] = replace(chunk, message_index_offsets=offsets, message_index_length=len(scan.tail))


def _topics(scan: FileScan) -> list[BagTopic]:
    topics = []
    for channel_id in sorted(scan.channel_info):
        schema_id, topic, metadata = scan.channel_info[channel_id]
        profiles = yaml.safe_load(metadata.get("offered_qos_profiles") or "[]") or []
        topics.append(
            BagTopic(
                channel_id,
                topic,
                scan.schema_names.get(schema_id, ""),
                tuple(OfferedQos.from_dict(p) for p in profiles),
                metadata.get("topic_type_hash", ""),
            )
        )
    return topics


def _custom_data(bag: Path) -> dict[str, str] | None:
    """custom_data of the bag's current metadata.yaml, if it has one."""
    try:
        document = yaml.safe_load((bag / METADATA_FILE).read_text(encoding="utf-8"))
        return document["rosbag2_bagfile_information"].get("custom_data") or None
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return None


def _scan_file(path: Path) -> FileScan:
    """The whole records of one MCAP file (BagRecoveryError if it is empty or not MCAP)."""
    if path.stat().st_size == 0:
        msg = f"{path}: empty file"
        raise BagRecoveryError(msg)
    with path.open("rb") as stream, mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as mapped:
        view = memoryview(mapped)
        try:
            return scan_records(view)
        finally:
            view.release()


def _complete_file(path: Path, scan: FileScan, information: dict[str, object]) -> None:
    """Cut ``path`` after its last whole record and append what closing it would have written."""
    stats = scan.statistics
    rosbag2 = metadata_record("rosbag2", {"serialized_metadata": dump_metadata(information, top_level=False)})
    scan.metadata_indexes.append(metadata_index_record(scan.append_at, len(rosbag2), "rosbag2"))
    stats.metadata_count += 1
    data_end = data_end_record()
    summary = summary_and_footer(
        scan.append_at + len(rosbag2) + len(data_end),
        schemas=scan.schemas,
        channels=[scan.channels[cid] for cid in sorted(scan.channels)],
        statistics=stats,
        chunk_indexes=scan.chunk_indexes,
        metadata_indexes=scan.metadata_indexes,
    )
    with path.open("r+b") as stream:
        stream.truncate(scan.end)
        stream.seek(scan.end)
        stream.write(scan.tail + rosbag2 + data_end + summary)
        stream.flush()
        os.fsync(stream.fileno())


def recover_bag(bag: Path | str) -> RecoveryResult:
    """Make a killed recorder's bag (every split file of it) complete and readable by every reader; returns what
    it kept. Files that are complete already stay untouched; metadata.yaml is rewritten if any was not."""
    bag = Path(bag)
    paths = bag_files(bag)
    if not paths:
        msg = f"{bag}: no MCAP file {mcap_file_of(bag).name}"
        raise BagRecoveryError(msg)
    scans = [(path, is_complete(path), path.stat().st_size, _scan_file(path)) for path in paths]
    topics = _topics(scans[0][3])  # every split file repeats the same schemas and channels
    names = {t.channel_id: t.name for t in topics}
    counts: dict[int, int] = {}
    spans = []
    for path, _, _, scan in scans:
        stats = scan.statistics
        for channel_id, n in stats.channel_message_counts.items():
            counts[channel_id] = counts.get(channel_id, 0) + n
        start, end = (stats.start_time, stats.end_time) if stats.message_count else (0, 0)
        spans.append(FileSpan(path.name, start, end, stats.message_count))
    with_messages = [span for span in spans if span.message_count]
    start = min((span.start_ns for span in with_messages), default=0)
    end = max((span.end_ns for span in with_messages), default=0)
    information = bag_metadata(spans, topics, counts, start, end, custom_data=_custom_data(bag))
    cut = [(path, size, scan) for path, complete, size, scan in scans if not complete]
    for path, _, scan in cut:
        _complete_file(path, scan, information)
    if cut:
        write_metadata_file(bag, information)
    return RecoveryResult(
        bag,
        bool(cut),
        sum(scan.statistics.message_count for *_, scan in scans),
        sum(scan.statistics.chunk_count for *_, scan in scans),
        sum(size - scan.end for _, size, scan in cut),
        {names[cid]: n for cid, n in sorted(counts.items()) if cid in names},
    )
