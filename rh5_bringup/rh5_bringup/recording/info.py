"""What a bag holds, read from its MCAP files (not from metadata.yaml, which a killed recorder leaves behind).

A complete file is described by its summary (statistics, chunk indexes, channels, schemas); a file
whose recorder was killed has none, so its whole records are scanned up to the cut (recovery.py's
scanner), which is what ``rh5 bag recover`` would keep. ``rh5 bag info`` prints :func:`format_bag_info`.
"""

from __future__ import annotations

import mmap
from collections import Counter
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from rh5_bringup.recording.bag import bag_files
from rh5_bringup.recording.errors import BagRecoveryError
from rh5_bringup.recording.mcap_format import (
    ChunkIndex,
    Opcode,
    Statistics,
    iter_records,
    parse_channel,
    parse_chunk_index,
    parse_footer,
    parse_schema,
    parse_statistics,
)
from rh5_bringup.recording.recovery import is_complete, scan_records

__all__ = ["BagInfo", "FileInfo", "TopicInfo", "format_bag_info", "read_bag_info"]


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a file: name, type, messages."""

    name: str
    type: str
    count: int


@dataclass(frozen=True)
class FileInfo:
    """One MCAP file of a bag."""

    path: Path
    size: int
    complete: bool
    """False: no summary and footer (the recorder was killed); the counts are those of its whole chunks."""
    statistics: Statistics
    chunks: tuple[ChunkIndex, ...]
    topics: tuple[TopicInfo, ...]

    @property
    def records_bytes(self) -> int:
        """Bytes of message records in the chunks, uncompressed."""
        return sum(c.records_size for c in self.chunks)

    @property
    def stored_bytes(self) -> int:
        """Bytes of message records as stored (compressed)."""
        return sum(c.records_size if c.stored_size is None else c.stored_size for c in self.chunks)

    @property
    def compressions(self) -> tuple[str, ...]:
        """The chunks' compressions (``none`` for uncompressed), each once."""
        return tuple(sorted({c.compression or "none" for c in self.chunks}))


@dataclass(frozen=True)
class BagInfo:
    """A bag folder: its MCAP files in split order."""

    path: Path
    files: tuple[FileInfo, ...]

    @property
    def complete(self) -> bool:
        """Whether every file has its summary and footer."""
        return all(f.complete for f in self.files)

    @property
    def message_count(self) -> int:
        """Messages in all files (whole chunks only, for an incomplete file)."""
        return sum(f.statistics.message_count for f in self.files)

    @property
    def start_ns(self) -> int:
        """The first log time (0 for an empty bag)."""
        starts = [f.statistics.start_time for f in self.files if f.statistics.message_count]
        return min(starts, default=0)

    @property
    def end_ns(self) -> int:
        """The last log time (0 for an empty bag)."""
        ends = [f.statistics.end_time for f in self.files if f.statistics.message_count]
        return max(ends, default=0)

    @property
    def topics(self) -> tuple[TopicInfo, ...]:
        """Every topic with its messages summed over the files, by name."""
        counts: Counter[str] = Counter()
        types: dict[str, str] = {}
        for file in self.files:
            for topic in file.topics:
                counts[topic.name] += topic.count
                types.setdefault(topic.name, topic.type)
        return tuple(TopicInfo(name, types[name], counts[name]) for name in sorted(types))


def _topics(schema_names: dict[int, str], channels: dict[int, tuple[int, str]], counts: dict[int, int]) -> tuple:
    return tuple(
        TopicInfo(topic, schema_names.get(schema_id, ""), counts.get(channel_id, 0))
        for channel_id, (schema_id, topic) in sorted(channels.items())
    )


def _from_summary(data: memoryview, summary_start: int) -> tuple[Statistics, list[ChunkIndex], tuple]:
    statistics, chunks = Statistics(), []
    schema_names: dict[int, str] = {}
    channels: dict[int, tuple[int, str]] = {}
    for record in iter_records(data, summary_start):
        if record.opcode == Opcode.SCHEMA:
            schema_id, name = parse_schema(record.content)
            schema_names[schema_id] = name
        elif record.opcode == Opcode.CHANNEL:
            channel_id, schema_id, topic, _, _ = parse_channel(record.content)
            channels[channel_id] = (schema_id, topic)
        elif record.opcode == Opcode.STATISTICS:
            statistics = parse_statistics(record.content)
        elif record.opcode == Opcode.CHUNK_INDEX:
            chunks.append(parse_chunk_index(record.content))
        elif record.opcode == Opcode.FOOTER:
            break
    return statistics, chunks, _topics(schema_names, channels, statistics.channel_message_counts)


def read_file_info(path: Path) -> FileInfo:
    """Describe one MCAP file (BagRecoveryError if it is not one)."""
    size = path.stat().st_size
    if size == 0:
        msg = f"{path}: empty file"
        raise BagRecoveryError(msg)
    complete = is_complete(path)
    with path.open("rb") as stream, mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as mapped:
        data = memoryview(mapped)
        try:
            summary_start = parse_footer(data) if complete else None
            if summary_start is not None:
                statistics, chunks, topics = _from_summary(data, summary_start)
            else:
                scan = scan_records(data)
                statistics, chunks = scan.statistics, scan.chunk_indexes
                channels = {cid: (schema_id, topic) for cid, (schema_id, topic, _) in scan.channel_info.items()}
                topics = _topics(scan.schema_names, channels, statistics.channel_message_counts)
        finally:
            data.release()
    return FileInfo(path, size, complete, statistics, tuple(chunks), topics)


def read_bag_info(bag: Path | str) -> BagInfo:
    """Describe a bag folder from its MCAP files (BagRecoveryError when it has none or one is not MCAP)."""
    bag = Path(bag)
    files = bag_files(bag)
    if not files:
        msg = f"{bag}: not a bag folder (no {bag.name}_<n>.mcap file)"
        raise BagRecoveryError(msg)
    return BagInfo(bag, tuple(read_file_info(f) for f in files))


def _stamp(ns: int) -> str:
    return datetime.fromtimestamp(ns / 1e9, UTC).isoformat(timespec="milliseconds") + f" ({ns} ns)"


def format_bag_info(info: BagInfo) -> str:
    """A text description of the bag, in the spirit of ``ros2 bag info``."""
    lines = [f"Bag:          {info.path}"]
    for file in info.files:
        state = "complete" if file.complete else "INCOMPLETE (no summary: run `rh5 bag recover`)"
        ratio = file.records_bytes / file.stored_bytes if file.stored_bytes else 1.0
        lines.append(
            f"File:         {file.path.name}  {file.size / 1e6:.1f} MB, {state}; "
            f"{file.statistics.message_count} messages in {len(file.chunks)} chunks, "
            f"compression {'+'.join(file.compressions) or 'none'} ({ratio:.1f}x)"
        )
    lines.append(f"Size:         {sum(f.size for f in info.files) / 1e6:.1f} MB")
    duration = (info.end_ns - info.start_ns) / 1e9
    lines.append(f"Duration:     {duration:.3f} s")
    if info.message_count:
        lines.append(f"Start:        {_stamp(info.start_ns)}")
        lines.append(f"End:          {_stamp(info.end_ns)}")
    lines.append(f"Messages:     {info.message_count}")
    topics = info.topics
    width = max((len(t.name) for t in topics), default=0)
    lines.append("Topics:")
    lines.extend(f"  {t.name:<{width}}  {t.count:>9}  {t.type}" for t in topics)
    return "\n".join(lines)
