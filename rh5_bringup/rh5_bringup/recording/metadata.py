"""rosbag2's ``metadata.yaml`` (format version 9, as rosbag2 Jazzy writes it) and its QoS profile entries.

Version 9 stores each topic's offered QoS profiles as a YAML list with lower-case enum names
(``keep_last``, ``best_effort``, ``transient_local``, ``automatic``) and durations as ``{sec, nsec}``;
an infinite duration, the default of every profile of the suite, is rmw's ``{9223372036, 854775807}``.
The same list, as YAML text, is the ``offered_qos_profiles`` entry of each MCAP channel.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import yaml

__all__ = [
    "INFINITE_DURATION",
    "METADATA_FILE",
    "METADATA_VERSION",
    "BagTopic",
    "FileSpan",
    "OfferedQos",
    "bag_metadata",
    "dump_metadata",
    "qos_profiles_yaml",
    "write_metadata_file",
]

METADATA_FILE: Final = "metadata.yaml"
METADATA_VERSION: Final = 9
"""rosbag2 Jazzy's metadata format version."""
INFINITE_DURATION: Final = {"sec": 9223372036, "nsec": 854775807}
"""rmw's RMW_DURATION_INFINITE as rosbag2 writes it."""
_ROS_DISTRO: Final = os.environ.get("ROS_DISTRO") or "jazzy"
_Dumper: Any = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _duration(ns: int | None) -> dict[str, int]:
    if ns is None or ns <= 0:
        return dict(INFINITE_DURATION)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _nanoseconds(duration: Mapping[str, int] | None) -> int | None:
    if not duration or dict(duration) == INFINITE_DURATION:
        return None
    return int(duration["sec"]) * 1_000_000_000 + int(duration["nsec"])


@dataclass(frozen=True)
class OfferedQos:
    """One offered QoS profile of a topic, with rosbag2's value names. Durations: None = infinite."""

    reliability: str
    durability: str
    history: str = "keep_last"
    depth: int = 1
    liveliness: str = "automatic"
    deadline_ns: int | None = None
    lifespan_ns: int | None = None
    liveliness_lease_duration_ns: int | None = None
    avoid_ros_namespace_conventions: bool = False

    @classmethod
    def from_dict(cls, entry: Mapping[str, Any]) -> OfferedQos:
        """A profile from one entry of ``offered_qos_profiles`` (version 9 names)."""
        return cls(
            reliability=str(entry["reliability"]),
            durability=str(entry["durability"]),
            history=str(entry.get("history", "keep_last")),
            depth=int(entry.get("depth", 1)),
            liveliness=str(entry.get("liveliness", "automatic")),
            deadline_ns=_nanoseconds(entry.get("deadline")),
            lifespan_ns=_nanoseconds(entry.get("lifespan")),
            liveliness_lease_duration_ns=_nanoseconds(entry.get("liveliness_lease_duration")),
            avoid_ros_namespace_conventions=bool(entry.get("avoid_ros_namespace_conventions", False)),
        )

    def to_dict(self) -> dict[str, Any]:
        """The profile as one entry of ``offered_qos_profiles`` (keys in rosbag2's order)."""
        return {
            "history": self.history,
            "depth": self.depth,
            "reliability": self.reliability,
            "durability": self.durability,
            "deadline": _duration(self.deadline_ns),
            "lifespan": _duration(self.lifespan_ns),
            "liveliness": self.liveliness,
            "liveliness_lease_duration": _duration(self.liveliness_lease_duration_ns),
            "avoid_ros_namespace_conventions": self.avoid_ros_namespace_conventions,
        }


def qos_profiles_yaml(profiles: Sequence[OfferedQos]) -> str:
    """The YAML text of a list of profiles (an MCAP channel's ``offered_qos_profiles`` entry)."""
    if not profiles:
        return ""
    return yaml.dump([p.to_dict() for p in profiles], Dumper=_Dumper, default_flow_style=False, sort_keys=False)


@dataclass(frozen=True)
class BagTopic:
    """A recorded topic: its channel id in the MCAP file and its rosbag2 topic metadata."""

    channel_id: int
    name: str
    type: str
    offered_qos: tuple[OfferedQos, ...]
    type_description_hash: str
    serialization_format: str = "cdr"

    def topic_metadata(self) -> dict[str, Any]:
        """The ``topic_metadata`` mapping of metadata.yaml."""
        return {
            "name": self.name,
            "type": self.type,
            "serialization_format": self.serialization_format,
            "offered_qos_profiles": [p.to_dict() for p in self.offered_qos],
            "type_description_hash": self.type_description_hash,
        }


@dataclass(frozen=True)
class FileSpan:
    """One MCAP file of a bag as metadata.yaml lists it: its name, first and last log time, messages."""

    path: str
    start_ns: int
    end_ns: int
    message_count: int

    def entry(self) -> dict[str, Any]:
        """The file's entry under ``files``."""
        return {
            "path": self.path,
            "starting_time": {"nanoseconds_since_epoch": self.start_ns},
            "duration": {"nanoseconds": max(0, self.end_ns - self.start_ns)},
            "message_count": self.message_count,
        }


def bag_metadata(
    files: str | Sequence[FileSpan],
    topics: Sequence[BagTopic],
    counts: Mapping[int, int],
    start_ns: int,
    end_ns: int,
    *,
    custom_data: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of an MCAP bag of one or several (split) files.

    ``files``: the files in split order (one file's name: the whole bag is that file); ``counts`` are
    messages per channel id over all files; ``start_ns``/``end_ns`` the first and last log time
    (rosbag2: receive time), the duration being their difference.
    """
    total = sum(counts.get(t.channel_id, 0) for t in topics)
    duration = max(0, end_ns - start_ns)
    if isinstance(files, str):
        files = [FileSpan(files, start_ns, end_ns, total)]
    return {
        "version": METADATA_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start_ns},
        "message_count": total,
        "topics_with_message_count": [
            {"topic_metadata": t.topic_metadata(), "message_count": counts.get(t.channel_id, 0)} for t in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [f.entry() for f in files],
        "custom_data": dict(custom_data) if custom_data else None,
        "ros_distro": _ROS_DISTRO,
    }


def dump_metadata(information: Mapping[str, Any], *, top_level: bool = True) -> str:
    """YAML text of the metadata: metadata.yaml (under ``rosbag2_bagfile_information``) or, without the
    top level, the ``serialized_metadata`` rosbag2 keeps in the MCAP file's ``rosbag2`` metadata record."""
    document = {"rosbag2_bagfile_information": dict(information)} if top_level else dict(information)
    return yaml.dump(document, Dumper=_Dumper, default_flow_style=False, sort_keys=False)


def write_metadata_file(bag: Path, information: Mapping[str, Any]) -> Path:
    """Write ``<bag>/metadata.yaml`` atomically (a reader never sees half a file); returns its path."""
    path = Path(bag) / METADATA_FILE
    tmp = path.with_name(f".{METADATA_FILE}.tmp")
    tmp.write_text(dump_metadata(information), encoding="utf-8")
    tmp.replace(path)
    return path
