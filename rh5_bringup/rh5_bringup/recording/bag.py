"""A rosbag2 bag as ``ros2 bag record -s mcap`` writes it: ``<bag>/metadata.yaml`` and ``<bag>/<bag>_0.mcap``
(``<bag>_1.mcap``, ... when it is split by size or duration, as ``--max-bag-size``/``--max-bag-duration`` do).

The MCAP file has the ``ros2`` profile, one ``ros2msg`` schema per message type (the full definition
text rosbag2 writes, rh5_msgs_py.schemas), one ``cdr`` channel per topic carrying the
``offered_qos_profiles`` and ``topic_type_hash`` metadata, zstd-compressed chunks (as rosbag2's
``zstd_fast`` preset; ``compression=""`` writes them uncompressed) with message indexes,
the summary rosbag2's writer produces and, on close, the ``rosbag2`` metadata record. Log time is
the receive time and publish time the sender's time, both in integer nanoseconds (rosbag2 Jazzy's
``recv_timestamp``/``send_timestamp``).

Crash safety: a chunk is written once it holds ``chunk_size`` bytes or its first message is
``chunk_max_age_s`` old (checked by :meth:`BagWriter.poll`), and metadata.yaml is rewritten
(atomically) at most every ``metadata_interval_s`` to describe what the file holds. A killed
writer leaves a bag whose MCAP is readable up to its last chunk; recovery.py completes it.

Splitting: before a message is written, the current file is finished (like ``close``, each file
complete on its own, with the same schemas and channel ids) and the next one opened when the file
has reached ``max_bag_size`` bytes on disk or the message's log time is ``max_bag_duration_s`` past
the file's first one (0: never).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from functools import cache, partial
from pathlib import Path
from types import TracebackType
from typing import Final, Self

from rh5_bringup.recording.compression import DEFAULT_COMPRESSION, DEFAULT_LEVEL
from rh5_bringup.recording.errors import BagWriterError
from rh5_bringup.recording.mcap_writer import DEFAULT_CHUNK_SIZE, McapStreamWriter
from rh5_bringup.recording.metadata import (
    BagTopic,
    FileSpan,
    OfferedQos,
    bag_metadata,
    dump_metadata,
    qos_profiles_yaml,
    write_metadata_file,
)

__all__ = [
    "DEFAULT_CHUNK_MAX_AGE_S",
    "LIBRARY",
    "BagWriter",
    "bag_files",
    "mcap_file_of",
    "type_description_hash",
]

LIBRARY: Final = "rh5_bringup.recording"
"""The MCAP header's library field."""
DEFAULT_CHUNK_MAX_AGE_S: Final = 0.5
"""A chunk is written at the latest this long after its first message: what a SIGKILL loses at most."""
DEFAULT_METADATA_INTERVAL_S: Final = 1.0


def mcap_file_of(bag: Path) -> Path:
    """The MCAP file of a bag folder, named like rosbag2's first split: ``<bag>/<bag>_0.mcap``."""
    bag = Path(bag)
    return bag / f"{bag.name}_0.mcap"


def bag_files(bag: Path) -> list[Path]:
    """The MCAP files of a bag folder in split order: ``<bag>_0.mcap``, ``<bag>_1.mcap``, ..."""
    bag = Path(bag)
    prefix = f"{bag.name}_"
    numbered = []
    for path in bag.glob(f"{prefix}*.mcap"):
        index = path.stem.removeprefix(prefix)
        if index.isdigit():
            numbered.append((int(index), path))
    return [path for _, path in sorted(numbered)]


@cache
def type_description_hash(type_name: str) -> str:
    """The RIHS01 type hash of ``pkg/msg/Type``, read from the type's ``.json`` description in the wheel."""
    from rh5_msgs_py.schemas import msg_file  # noqa: PLC0415 (rh5_msgs_py imports rclpy; only needed here)

    description = json.loads(msg_file(type_name).with_suffix(".json").read_text(encoding="utf-8"))
    for entry in description["type_hashes"]:
        if entry["type_name"] == type_name:
            return str(entry["hash_string"])
    msg = f"no type hash for {type_name!r} in its type description"
    raise BagWriterError(msg)


def _message_definition(type_name: str) -> str:
    from rh5_msgs_py.schemas import message_definition  # noqa: PLC0415 (see type_description_hash)

    return message_definition(type_name)


class BagWriter:
    """Writes one bag: ``open``, ``add_topic``, ``write`` (+ ``poll`` now and then), ``close``. A context manager.

    Not thread-safe: one thread owns it (the recorder's writer thread).
    """

    def __init__(
        self,
        path: Path | str,
        *,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        chunk_max_age_s: float = DEFAULT_CHUNK_MAX_AGE_S,
        metadata_interval_s: float = DEFAULT_METADATA_INTERVAL_S,
        compression: str = DEFAULT_COMPRESSION,
        compression_level: int = DEFAULT_LEVEL,
        max_bag_size: int = 0,
        max_bag_duration_s: float = 0.0,
        custom_data: Mapping[str, str] | None = None,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        if max_bag_size < 0 or max_bag_duration_s < 0:
            msg = f"max_bag_size and max_bag_duration_s must be >= 0, got {max_bag_size}, {max_bag_duration_s}"
            raise ValueError(msg)
        self.path = Path(path)
        self.custom_data = dict(custom_data or {})
        self.max_bag_size = max_bag_size
        self._max_duration_ns = int(max_bag_duration_s * 1e9)
        self._new_file = partial(
            McapStreamWriter,
            profile="ros2",
            library=LIBRARY,
            chunk_size=chunk_size,
            compression=compression,
            compression_level=compression_level,
        )
        self._mcap = self._new_file(mcap_file_of(self.path))
        self._finished_files: list[FileSpan] = []
        self._finished_counts: list[dict[int, int]] = []
        self._chunks_before = 0
        self._file_first_ns: int | None = None
        self._schema_records: list[tuple[str, bytes]] = []
        self._channel_records: list[tuple[str, int, dict[str, str]]] = []
        self._max_age_ns = int(chunk_max_age_s * 1e9)
        self._metadata_interval_ns = int(metadata_interval_s * 1e9)
        self._clock = clock
        self._topics: dict[int, BagTopic] = {}
        self._schemas: dict[str, int] = {}
        self._counts: dict[int, int] = {}
        self._chunk_opened_ns: int | None = None
        self._metadata_written_ns = 0
        self._metadata_chunks = -1
        self._opened_wall_ns = 0
        self._closed = False

    # --- lifecycle -------------------------------------------------------------------------------------------

    def open(self) -> None:
        """Create the bag folder (never an existing one), the MCAP file and a first metadata.yaml."""
        try:
            self.path.mkdir(parents=True)
        except FileExistsError:
            msg = f"{self.path} exists already, not overwriting it"
            raise BagWriterError(msg) from None
        self._opened_wall_ns = time.time_ns()
        self._mcap.open()
        self._write_metadata()

    def close(self) -> None:
        """Write what is pending, the ``rosbag2`` metadata record, the summary and the final metadata.yaml.

        Idempotent; a bag that was never opened is left alone.
        """
        if self._closed or not self._mcap.is_open:
            return
        information = self._finish_file()
        self._closed = True
        write_metadata_file(self.path, information)

    @property
    def mcap_path(self) -> Path:
        """The MCAP file being written (the last one once closed)."""
        return self._mcap.path

    @property
    def files(self) -> list[Path]:
        """The bag's MCAP files so far, in split order."""
        return [self.path / f.path for f in self._finished_files] + ([] if self._closed else [self._mcap.path])

    def abort(self) -> None:
        """Stop writing without finishing the file (what a crash leaves, minus the open chunk). Idempotent."""
        self._mcap.abort()
        self._closed = True

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()

    # --- content ---------------------------------------------------------------------------------------------

    def add_topic(
        self,
        name: str,
        type_name: str,
        offered_qos: Sequence[OfferedQos] = (),
        *,
        definition: str | None = None,
        type_hash: str | None = None,
    ) -> int:
        """Register a topic (once); returns the id to :meth:`write` its messages with.

        ``definition`` (ros2msg text) and ``type_hash`` (RIHS01) default to those of the installed type.
        """
        if any(t.name == name for t in self._topics.values()):
            msg = f"topic {name!r} was added already"
            raise BagWriterError(msg)
        if not self._mcap.is_open:
            msg = f"{self.path}: open the bag before adding topics"
            raise BagWriterError(msg)
        type_hash = type_description_hash(type_name) if type_hash is None else type_hash
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            text = (_message_definition(type_name) if definition is None else definition).encode("utf-8")
            schema_id = self._schemas[type_name] = self._mcap.add_schema(type_name, "ros2msg", text)
            self._schema_records.append((type_name, text))
        qos = tuple(offered_qos)
        metadata = {"offered_qos_profiles": qos_profiles_yaml(qos), "topic_type_hash": type_hash}
        channel_id = self._mcap.add_channel(name, "cdr", schema_id, metadata)
        self._channel_records.append((name, schema_id, metadata))
        self._topics[channel_id] = BagTopic(channel_id, name, type_name, qos, type_hash)
        self._counts[channel_id] = 0
        return channel_id

    def write(
        self, topic_id: int, log_time: int, data: bytes | memoryview, publish_time: int | None = None, sequence: int = 0
    ) -> None:
        """Write one serialized (CDR) message; times in integer nanoseconds (publish time defaults to log time)."""
        first = self._file_first_ns
        if first is None:
            self._file_first_ns = log_time
        elif (self.max_bag_size and self._mcap.position >= self.max_bag_size) or (
            self._max_duration_ns and log_time - first >= self._max_duration_ns
        ):
            self._split()
            self._file_first_ns = log_time
        mcap = self._mcap
        if mcap.pending_messages == 0:
            self._chunk_opened_ns = self._clock()
        mcap.write_message(topic_id, log_time, log_time if publish_time is None else publish_time, data, sequence)
        self._counts[topic_id] += 1

    def poll(self) -> bool:
        """Write the open chunk if it is old enough and refresh metadata.yaml if due; True if a chunk was written."""
        now = self._clock()
        written = False
        opened = self._chunk_opened_ns
        if self._mcap.pending_messages and opened is not None and now - opened >= self._max_age_ns:
            written = self._mcap.close_chunk()
        if self._chunks_before + self._mcap.statistics.chunk_count != self._metadata_chunks and (
            now - self._metadata_written_ns >= self._metadata_interval_ns
        ):
            self._write_metadata()
            self._metadata_written_ns = now
        return written

    def flush(self) -> None:
        """Write the open chunk and metadata.yaml now."""
        self._mcap.close_chunk()
        self._write_metadata()

    # --- state -----------------------------------------------------------------------------------------------

    @property
    def topics(self) -> tuple[BagTopic, ...]:
        """The registered topics in channel-id order."""
        return tuple(self._topics[cid] for cid in sorted(self._topics))

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic name (including those of the chunk not yet in the file)."""
        return {self._topics[cid].name: n for cid, n in sorted(self._counts.items())}

    @property
    def message_count(self) -> int:
        """Messages written in all."""
        return sum(self._counts.values())

    @property
    def pending_messages(self) -> int:
        """Messages of the open chunk (lost if the process is killed now)."""
        return self._mcap.pending_messages

    # --- internals -------------------------------------------------------------------------------------------

    def _current_span(self) -> FileSpan:
        stats = self._mcap.statistics
        start, end = (stats.start_time, stats.end_time) if stats.message_count else (self._opened_wall_ns,) * 2
        return FileSpan(self._mcap.path.name, start, end, stats.message_count)

    def _information(self) -> dict[str, object]:
        """The metadata of what the MCAP files hold so far (complete chunks only)."""
        spans = [*self._finished_files, self._current_span()]
        counts = dict(self._mcap.statistics.channel_message_counts)
        for span_counts in self._finished_counts:
            for channel_id, n in span_counts.items():
                counts[channel_id] = counts.get(channel_id, 0) + n
        with_messages = [s for s in spans if s.message_count] or spans[-1:]
        start = min(s.start_ns for s in with_messages)
        end = max(s.end_ns for s in with_messages)
        return bag_metadata(spans, self.topics, counts, start, end, custom_data=self.custom_data or None)

    def _finish_file(self) -> dict[str, object]:
        """Write the open chunk, the ``rosbag2`` metadata record, the summary and the footer of the current file;
        returns the bag's metadata including it."""
        self._mcap.close_chunk()
        information = self._information()
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": dump_metadata(information, top_level=False)})
        self._mcap.finish()
        return information

    def _split(self) -> None:
        """Finish the current file and continue in the next, with the same schemas and channel ids."""
        self._finish_file()
        self._finished_files.append(self._current_span())
        self._finished_counts.append(dict(self._mcap.statistics.channel_message_counts))
        self._chunks_before += self._mcap.statistics.chunk_count
        path = self.path / f"{self.path.name}_{len(self._finished_files)}.mcap"
        self._mcap = self._new_file(path)
        self._mcap.open()
        for type_name, text in self._schema_records:
            self._mcap.add_schema(type_name, "ros2msg", text)
        for name, schema_id, metadata in self._channel_records:
            self._mcap.add_channel(name, "cdr", schema_id, metadata)
        self._write_metadata()

    def _write_metadata(self) -> None:
        write_metadata_file(self.path, self._information())
        self._metadata_chunks = self._chunks_before + self._mcap.statistics.chunk_count
