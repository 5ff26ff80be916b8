"""The bag writer without ROS: round trips through rosbags and mcap-ros2-support, crash safety and recovery.

Messages are serialized with rosbags' own CDR serializer (an implementation independent of this
writer) and read back with two independent readers: rosbags (AnyReader on the bag folder, as the
report generator does) and mcap + mcap_ros2 (CRC-checked, decoding every message).
"""

from __future__ import annotations

import struct
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.exceptions import EndOfFile
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosHistory, QosReliability
from rosbags.rosbag2 import Reader, ReaderError
from rosbags.typesys import Stores, get_typestore

from rh5_bringup.recording import (
    BagRecoveryError,
    BagWriter,
    BagWriterError,
    OfferedQos,
    QueuedBagWriter,
    bag_files,
    format_bag_info,
    is_complete,
    mcap_file_of,
    read_bag_info,
    recover_bag,
    type_description_hash,
)
from rh5_bringup.recording.mcap_format import Opcode, iter_records
from rh5_msgs_py.schemas import message_definition

JAZZY = get_typestore(Stores.ROS2_JAZZY)
JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH = "geometry_msgs/msg/WrenchStamped"
STRING = "std_msgs/msg/String"
STREAM = OfferedQos("best_effort", "volatile", depth=1)
LATCHED = OfferedQos("reliable", "transient_local", depth=1)
T0 = 1_700_000_000_000_000_000


def joint_state(i: int, n: int = 32) -> bytes:
    """A JointState whose values encode ``i`` (header stamp i ms, position[k] = i + k/100)."""
    msg = JAZZY.types[JOINT_STATE](
        header=JAZZY.types["std_msgs/msg/Header"](
            stamp=JAZZY.types["builtin_interfaces/msg/Time"](sec=i // 1000, nanosec=(i % 1000) * 1_000_000),
            frame_id="",
        ),
        name=[f"joint_{k}" for k in range(n)],
        position=i + np.arange(n) / 100.0,
        velocity=np.full(n, -float(i)),
        effort=np.array([], dtype=np.float64),
    )
    return bytes(JAZZY.serialize_cdr(msg, JOINT_STATE))


def wrench(i: int) -> bytes:
    """A WrenchStamped with force.z = i."""
    types = JAZZY.types
    msg = types[WRENCH](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="sole"
        ),
        wrench=types["geometry_msgs/msg/Wrench"](
            force=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=float(i)),
            torque=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
        ),
    )
    return bytes(JAZZY.serialize_cdr(msg, WRENCH))


def string(text: str) -> bytes:
    return bytes(JAZZY.serialize_cdr(JAZZY.types[STRING](data=text), STRING))


class FakeClock:
    """A monotonic clock the test advances by hand (ns)."""

    def __init__(self) -> None:
        self.now = 0

    def __call__(self) -> int:
        return self.now


def write_session(bag: BagWriter, n_states: int = 500) -> dict[str, list[tuple[int, bytes]]]:
    """Three topics: 1 kHz joint states, 100 Hz wrenches, one latched string. Returns what was written."""
    states = bag.add_topic("/joint_states", JOINT_STATE, [STREAM])
    wrenches = bag.add_topic(
        "/sim/wrench/left_foot",
        WRENCH,
        [STREAM],
        definition=message_definition(WRENCH),
        type_hash=JAZZY.hash_rihs01(WRENCH),
    )
    latched = bag.add_topic("/robot_description", STRING, [LATCHED])
    written: dict[str, list[tuple[int, bytes]]] = {
        "/joint_states": [],
        "/sim/wrench/left_foot": [],
        "/robot_description": [],
    }
    description = string("<robot name='rh5'/>")
    bag.write(latched, T0, description, publish_time=T0 - 1000, sequence=1)
    written["/robot_description"].append((T0, description))
    for i in range(n_states):
        t = T0 + (i + 1) * 1_000_000
        data = joint_state(i)
        bag.write(states, t, data, publish_time=t - 50_000, sequence=i + 1)
        written["/joint_states"].append((t, data))
        if i % 10 == 0:
            w = wrench(i)
            bag.write(wrenches, t + 1, w, sequence=i // 10 + 1)
            written["/sim/wrench/left_foot"].append((t + 1, w))
    return written


@pytest.fixture(params=["zstd", ""], ids=["zstd", "uncompressed"])
def compression(request: pytest.FixtureRequest) -> str:
    """Every bag test runs with zstd chunks (the default) and with uncompressed ones."""
    return str(request.param)


@pytest.fixture
def closed_bag(tmp_path: Path, compression: str) -> tuple[Path, dict[str, list[tuple[int, bytes]]]]:
    """A bag of three topics, written in many small chunks and closed."""
    path = tmp_path / "session"
    with BagWriter(path, chunk_size=16 * 1024, compression=compression) as bag:
        written = write_session(bag)
    return path, written


# --- round trip -------------------------------------------------------------------------------------------------


def test_the_folder_has_metadata_yaml_and_one_mcap_named_like_rosbag2(closed_bag: Any) -> None:
    path, written = closed_bag
    assert sorted(p.name for p in path.iterdir()) == ["metadata.yaml", "session_0.mcap"]
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == ["session_0.mcap"]
    assert info["compression_format"] == info["compression_mode"] == ""
    total = sum(len(v) for v in written.values())
    assert info["message_count"] == total
    assert info["files"] == [
        {
            "path": "session_0.mcap",
            "starting_time": info["starting_time"],
            "duration": info["duration"],
            "message_count": total,
        }
    ]
    times = [t for v in written.values() for t, _ in v]
    assert info["starting_time"]["nanoseconds_since_epoch"] == min(times)
    assert info["duration"]["nanoseconds"] == max(times) - min(times)
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {name: t["message_count"] for name, t in topics.items()} == {k: len(v) for k, v in written.items()}
    state = topics["/joint_states"]["topic_metadata"]
    assert state["type"] == JOINT_STATE
    assert state["serialization_format"] == "cdr"
    assert state["type_description_hash"] == JAZZY.hash_rihs01(JOINT_STATE)
    (profile,) = state["offered_qos_profiles"]
    assert profile["reliability"] == "best_effort"
    assert profile["durability"] == "volatile"
    assert profile["deadline"] == {"sec": 9223372036, "nsec": 854775807}


def test_rosbags_reads_every_message_back_exactly(closed_bag: Any) -> None:
    path, written = closed_bag
    with AnyReader([path]) as reader:
        connections = {c.topic: c for c in reader.connections}
        assert {t: c.msgcount for t, c in connections.items()} == {k: len(v) for k, v in written.items()}
        assert connections["/joint_states"].digest == JAZZY.hash_rihs01(JOINT_STATE)
        (qos,) = connections["/robot_description"].ext.offered_qos_profiles
        assert (qos.reliability, qos.durability, qos.history) == (
            QosReliability.RELIABLE,
            QosDurability.TRANSIENT_LOCAL,
            QosHistory.KEEP_LAST,
        )
        got: dict[str, list[tuple[int, bytes]]] = {k: [] for k in written}
        for connection, timestamp, raw in reader.messages():
            got[connection.topic].append((timestamp, bytes(raw)))
            reader.deserialize(raw, connection.msgtype)  # every message decodes with the bag's own schemas
        assert got == written
        last = reader.deserialize(got["/joint_states"][-1][1], JOINT_STATE)
        np.testing.assert_allclose(last.position, 499 + np.arange(32) / 100.0)
    with Reader(path) as plain:
        assert plain.message_count == sum(len(v) for v in written.values())


def test_mcap_ros2_decodes_every_message_with_crcs_and_summary(closed_bag: Any, compression: str) -> None:
    path, written = closed_bag
    with mcap_file_of(path).open("rb") as stream:
        reader = make_reader(stream, validate_crcs=True, decoder_factories=[DecoderFactory()])
        header, summary = reader.get_header(), reader.get_summary()
        assert header.profile == "ros2"
        assert summary is not None
        assert summary.statistics.message_count == sum(len(v) for v in written.values())
        assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 10
        for index in summary.chunk_indexes:
            assert index.compression == compression
            if compression:  # JointStates of a counter compress well
                assert index.compressed_size < index.uncompressed_size / 2
            else:
                assert index.compressed_size == index.uncompressed_size
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {JOINT_STATE, WRENCH, STRING}
        assert all(s.encoding == "ros2msg" for s in schemas.values())
        assert schemas[JOINT_STATE].data.decode() == message_definition(JOINT_STATE)
        channels = {c.topic: c for c in summary.channels.values()}
        assert all(c.message_encoding == "cdr" for c in channels.values())
        assert channels["/joint_states"].metadata["topic_type_hash"] == type_description_hash(JOINT_STATE)
        assert yaml.safe_load(channels["/joint_states"].metadata["offered_qos_profiles"])[0]["depth"] == 1
        decoded: dict[str, list[Any]] = {k: [] for k in written}
        for _, channel, message, ros_msg in reader.iter_decoded_messages(log_time_order=False):
            decoded[channel.topic].append((message, ros_msg))
        rosbag2_record = next(m for m in reader.iter_metadata() if m.name == "rosbag2")
    assert {k: len(v) for k, v in decoded.items()} == {k: len(v) for k, v in written.items()}
    for i, (message, ros_msg) in enumerate(decoded["/joint_states"]):
        assert message.sequence == i + 1
        assert message.publish_time == message.log_time - 50_000
        assert ros_msg.position[3] == pytest.approx(i + 0.03)
        assert ros_msg.header.stamp.nanosec == (i % 1000) * 1_000_000
    assert [m.wrench.force.z for _, m in decoded["/sim/wrench/left_foot"]] == [float(i) for i in range(0, 500, 10)]
    assert decoded["/robot_description"][0][1].data == "<robot name='rh5'/>"
    assert decoded["/sim/wrench/left_foot"][0][0].publish_time == decoded["/sim/wrench/left_foot"][0][0].log_time
    serialized = yaml.safe_load(rosbag2_record.metadata["serialized_metadata"])
    assert serialized == yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def test_log_times_out_of_order_are_indexed_in_order(tmp_path: Path) -> None:
    """Messages queued from several topics reach the writer slightly out of time order; indexes stay sorted."""
    path = tmp_path / "unordered"
    times = [T0 + 5, T0 + 1, T0 + 3, T0 + 2, T0 + 4]
    with BagWriter(path) as bag:
        topic = bag.add_topic("/chatter", STRING, [LATCHED])
        for k, t in enumerate(times):
            bag.write(topic, t, string(str(k)))
    with mcap_file_of(path).open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        in_time_order = [(m.log_time, d.data) for _, _, m, d in reader.iter_decoded_messages(log_time_order=True)]
    assert in_time_order == sorted((t, str(k)) for k, t in enumerate(times))


def test_a_message_larger_than_a_chunk_gets_a_chunk_of_its_own(tmp_path: Path) -> None:
    path = tmp_path / "big"
    urdf = "x" * 200_000
    with BagWriter(path, chunk_size=4096) as bag:
        topic = bag.add_topic("/robot_description", STRING, [LATCHED])
        bag.write(topic, T0, string("small"))
        bag.write(topic, T0 + 1, string(urdf))
        bag.write(topic, T0 + 2, string("after"))
    with AnyReader([path]) as reader:
        texts = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()]
    assert texts == ["small", urdf, "after"]


def test_an_empty_bag_is_valid(tmp_path: Path) -> None:
    path = tmp_path / "empty"
    with BagWriter(path) as bag:
        bag.add_topic("/joint_states", JOINT_STATE, [STREAM])
    with AnyReader([path]) as reader:
        assert [c.msgcount for c in reader.connections] == [0]
        assert list(reader.messages()) == []


# --- lifecycle ----------------------------------------------------------------------------------------------------


def test_an_existing_folder_is_never_overwritten(tmp_path: Path) -> None:
    (tmp_path / "taken").mkdir()
    marker = tmp_path / "taken" / "keep.txt"
    marker.write_text("mine")
    with pytest.raises(BagWriterError, match="exists already"):
        BagWriter(tmp_path / "taken").open()
    assert marker.read_text() == "mine"
    assert sorted(p.name for p in (tmp_path / "taken").iterdir()) == ["keep.txt"]


def test_lifecycle_misuse_is_refused(tmp_path: Path) -> None:
    bag = BagWriter(tmp_path / "b")
    with pytest.raises(BagWriterError, match="open the bag"):
        bag.add_topic("/a", STRING)
    bag.open()
    topic = bag.add_topic("/a", STRING, [LATCHED])
    with pytest.raises(BagWriterError, match="added already"):
        bag.add_topic("/a", STRING)
    with pytest.raises(BagWriterError, match="unknown channel"):
        bag.write(topic + 1, T0, string("x"))
    bag.close()
    bag.close()  # idempotent
    with pytest.raises(BagWriterError, match="finished"):
        bag.write(topic, T0, string("x"))


# --- crash safety -------------------------------------------------------------------------------------------------


def metadata_counts(path: Path) -> dict[str, int]:
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}


def test_an_old_chunk_is_written_and_metadata_follows(tmp_path: Path) -> None:
    """Size alone would keep these messages in memory; the age rule writes them within chunk_max_age_s."""
    clock = FakeClock()
    path = tmp_path / "aged"
    bag = BagWriter(path, chunk_max_age_s=0.5, metadata_interval_s=1.0, clock=clock)
    bag.open()
    topic = bag.add_topic("/joint_states", JOINT_STATE, [STREAM])
    for i in range(3):
        bag.write(topic, T0 + i, joint_state(i))
    clock.now = 400_000_000
    assert not bag.poll()
    assert bag.pending_messages == 3
    size_before = mcap_file_of(path).stat().st_size
    clock.now = 1_000_000_000
    assert bag.poll()
    assert bag.pending_messages == 0
    assert mcap_file_of(path).stat().st_size > size_before
    assert len(stream_messages(mcap_file_of(path))) == 3
    assert metadata_counts(path) == {"/joint_states": 3}
    bag.write(topic, T0 + 10, joint_state(10))
    clock.now = 1_600_000_000
    assert bag.poll()
    assert metadata_counts(path) == {"/joint_states": 3}, "metadata.yaml is rewritten at most once per interval"
    clock.now = 2_100_000_000
    bag.poll()
    assert metadata_counts(path) == {"/joint_states": 4}
    bag.abort()


def stream_messages(path: Path) -> list[Message]:
    """Messages a streaming reader gets out of a (possibly cut) MCAP file before it ends."""
    messages = []
    with path.open("rb") as stream:
        try:
            for record in StreamReader(stream, validate_crcs=True).records:
                if isinstance(record, Message):
                    messages.append(record)
        except (EndOfFile, struct.error):  # the cut: a record ends early
            pass
    return messages


def chunk_ends(path: Path) -> list[int]:
    """File offsets right after each chunk record."""
    data = memoryview(path.read_bytes())
    return [r.offset + r.length for r in iter_records(data) if r.opcode == Opcode.CHUNK]


@pytest.fixture
def crashed_bag(tmp_path: Path, compression: str) -> tuple[Path, dict[str, list[tuple[int, bytes]]], int]:
    """A bag whose writer died: complete chunks on disk, the open chunk lost. Returns (bag, written, kept)."""
    path = tmp_path / "crashed"
    bag = BagWriter(path, chunk_size=16 * 1024, compression=compression)
    bag.open()
    written = write_session(bag, n_states=300)
    kept = bag.message_count - bag.pending_messages
    assert 0 < kept < bag.message_count
    bag.abort()  # like SIGKILL: no summary, no footer, the open chunk never reaches the file
    return path, written, kept


def test_a_killed_writers_file_is_readable_up_to_its_last_chunk(crashed_bag: Any) -> None:
    path, _, kept = crashed_bag
    mcap = mcap_file_of(path)
    assert not is_complete(mcap)
    messages = stream_messages(mcap)
    assert len(messages) == kept
    with pytest.raises(ReaderError):  # rosbags needs the footer: recover_bag adds it
        Reader(path).open()
    assert sum(metadata_counts(path).values()) <= kept


@pytest.mark.parametrize("cut", ["inside_last_chunk", "after_last_chunk", "inside_message_index", "after_header"])
def test_recovery_keeps_every_whole_chunk_and_readers_accept_the_bag(crashed_bag: Any, cut: str) -> None:
    path, written, _ = crashed_bag
    mcap = mcap_file_of(path)
    ends = chunk_ends(mcap)
    data = mcap.read_bytes()
    cut_at = {
        "inside_last_chunk": ends[-1] - 100,
        "after_last_chunk": ends[-1],
        "inside_message_index": ends[-1] + 20,
        "after_header": ends[0] - 1,
    }[cut]
    mcap.write_bytes(data[:cut_at])
    whole_end = max(r.offset + r.length for r in iter_records(memoryview(data[:cut_at])))
    readable = stream_messages(mcap)
    result = recover_bag(path)
    assert result.recovered
    assert result.message_count == len(readable)
    rebuilt = cut in ("after_last_chunk", "inside_message_index")  # the last chunk's indexes are written anew
    assert result.discarded_bytes == cut_at - (ends[-1] if rebuilt else whole_end)
    assert is_complete(mcap)
    with AnyReader([path]) as reader:
        got: dict[str, list[tuple[int, bytes]]] = {k: [] for k in written}
        for connection, timestamp, raw in reader.messages():
            got[connection.topic].append((timestamp, bytes(raw)))
            reader.deserialize(raw, connection.msgtype)
    assert sum(len(v) for v in got.values()) == len(readable)
    for topic, messages in got.items():  # what survives is the beginning of what was written, per topic
        assert messages == sorted(messages)
        assert messages == written[topic][: len(messages)]
    if cut != "after_header":
        assert len(got["/joint_states"]) > 100
    assert sum(metadata_counts(path).values()) == len(readable)
    with mcap.open("rb") as stream:
        summary = make_reader(stream, validate_crcs=True).get_summary()
        assert summary is not None
        assert summary.statistics.message_count == len(readable)
    again = recover_bag(path)
    assert not again.recovered
    assert again.message_count == len(readable)


def test_recovering_a_complete_bag_changes_nothing(closed_bag: Any) -> None:
    path, _ = closed_bag
    before = {p.name: p.read_bytes() for p in path.iterdir()}
    result = recover_bag(path)
    assert not result.recovered
    assert result.counts["/joint_states"] == 500
    assert {p.name: p.read_bytes() for p in path.iterdir()} == before


def test_bag_info_reads_a_complete_bag_from_its_summary(closed_bag: Any, compression: str) -> None:
    path, written = closed_bag
    info = read_bag_info(path)
    assert info.complete
    assert [f.path.name for f in info.files] == ["session_0.mcap"]
    assert {t.name: t.count for t in info.topics} == {k: len(v) for k, v in written.items()}
    assert {t.name: t.type for t in info.topics}["/joint_states"] == JOINT_STATE
    times = [t for v in written.values() for t, _ in v]
    assert (info.start_ns, info.end_ns) == (min(times), max(times))
    (file,) = info.files
    assert file.compressions == (compression or "none",)
    assert file.records_bytes > 500 * 32 * 8
    assert (file.stored_bytes < file.records_bytes / 2) if compression else (file.stored_bytes == file.records_bytes)
    text = format_bag_info(info)
    assert "complete" in text
    assert "INCOMPLETE" not in text
    assert f"Messages:     {sum(len(v) for v in written.values())}" in text


def test_bag_info_of_a_killed_bag_counts_its_whole_chunks_and_says_to_recover(crashed_bag: Any) -> None:
    path, written, kept = crashed_bag
    info = read_bag_info(path)
    assert not info.complete
    assert info.message_count == kept == len(stream_messages(mcap_file_of(path)))
    assert "INCOMPLETE (no summary: run `rh5 bag recover`)" in format_bag_info(info)
    recover_bag(path)
    after = read_bag_info(path)
    assert after.complete
    assert {t.name: t.count for t in after.topics} == {t.name: t.count for t in info.topics}
    assert sum(t.count for t in after.topics) == kept < sum(len(v) for v in written.values())


def test_bag_info_refuses_a_folder_without_mcap_files(tmp_path: Path) -> None:
    with pytest.raises(BagRecoveryError, match="not a bag folder"):
        read_bag_info(tmp_path)


# --- splitting ----------------------------------------------------------------------------------------------------


def read_all(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of a bag folder, per topic, as rosbags reads it (all split files, via metadata.yaml)."""
    got: dict[str, list[tuple[int, bytes]]] = {}
    with AnyReader([path]) as reader:
        for connection, timestamp, raw in reader.messages():
            got.setdefault(connection.topic, []).append((timestamp, bytes(raw)))
            reader.deserialize(raw, connection.msgtype)
    return got


def mcap_summary(path: Path) -> Any:
    """The summary mcap's seeking reader finds in one file (CRC-checked)."""
    with path.open("rb") as stream:
        summary = make_reader(stream, validate_crcs=True).get_summary()
    assert summary is not None, path
    return summary


def test_a_bag_split_by_size_is_read_whole_and_every_file_stands_alone(tmp_path: Path, compression: str) -> None:
    path = tmp_path / "sized"
    limit = 64 * 1024
    with BagWriter(path, chunk_size=8 * 1024, compression=compression, max_bag_size=limit) as bag:
        written = write_session(bag, n_states=2000)
        files = bag.files
    assert [f.name for f in files] == [f"sized_{k}.mcap" for k in range(len(files))]
    assert len(files) >= 3
    assert bag_files(path) == files
    assert all(f.stat().st_size >= limit for f in files[:-1]), "a file is split only once it reached the limit"
    assert read_all(path) == written
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["relative_file_paths"] == [f.name for f in files]
    per_file = [mcap_summary(f).statistics.message_count for f in files]
    assert [f["message_count"] for f in info["files"]] == per_file
    assert sum(per_file) == info["message_count"] == sum(len(v) for v in written.values())
    for f in files:
        summary = mcap_summary(f)
        assert {c.topic for c in summary.channels.values()} == set(written)
    assert read_bag_info(path).message_count == sum(per_file)


def test_a_bag_split_by_duration_starts_a_file_per_period_of_log_time(tmp_path: Path) -> None:
    path = tmp_path / "timed"
    with BagWriter(path, chunk_size=16 * 1024, max_bag_duration_s=1.0) as bag:
        topic = bag.add_topic("/joint_states", JOINT_STATE, [STREAM])
        for i in range(2500):  # 2.5 s at 1 kHz
            bag.write(topic, T0 + i * 1_000_000, joint_state(i, n=4))
        files = bag.files
    assert len(files) == 3
    spans = []
    for f in files:
        stats = mcap_summary(f).statistics
        spans.append((stats.message_start_time, stats.message_end_time, stats.message_count))
    assert [n for *_, n in spans] == [1000, 1000, 500]
    assert [start for start, *_ in spans] == [T0, T0 + 1_000_000_000, T0 + 2_000_000_000]
    assert len(read_all(path)["/joint_states"]) == 2500


def test_a_killed_split_bag_is_recovered_file_by_file(tmp_path: Path) -> None:
    path = tmp_path / "killed_split"
    bag = BagWriter(path, chunk_size=8 * 1024, max_bag_size=48 * 1024, compression="")
    bag.open()
    written = write_session(bag, n_states=1500)
    files = bag.files
    kept = bag.message_count - bag.pending_messages
    bag.abort()
    assert len(files) >= 2
    finished = {f: f.read_bytes() for f in files[:-1]}
    assert all(is_complete(f) for f in finished)
    assert not is_complete(files[-1])
    result = recover_bag(path)
    assert result.recovered
    assert result.message_count == kept
    assert {f: f.read_bytes() for f in files[:-1]} == finished, "complete files are left alone"
    got = read_all(path)
    assert sum(len(v) for v in got.values()) == kept
    for topic, messages in got.items():
        assert messages == written[topic][: len(messages)]
    assert sum(mcap_summary(f).statistics.message_count for f in files) == kept


# --- the queued writer --------------------------------------------------------------------------------------------


def test_queued_writer_writes_everything_put_from_another_thread(tmp_path: Path) -> None:
    path = tmp_path / "queued"
    bag = BagWriter(path, chunk_size=8 * 1024)
    bag.open()
    topic = bag.add_topic("/joint_states", JOINT_STATE, [STREAM])
    writer = QueuedBagWriter(bag, period_s=0.002)
    writer.start()
    payloads = [joint_state(i, n=4) for i in range(2000)]

    def produce() -> None:
        for i, data in enumerate(payloads):
            assert writer.try_put(topic, T0 + i, T0 + i, i + 1, data)

    producer = threading.Thread(target=produce)
    producer.start()
    producer.join()
    writer.stop()
    assert writer.error is None
    assert not writer.dropped
    assert writer.sequence_gaps == {}
    with AnyReader([path]) as reader:
        assert [bytes(raw) for _, _, raw in reader.messages()] == payloads


def test_queued_writer_counts_drops_when_full_and_sequence_gaps(tmp_path: Path) -> None:
    bag = BagWriter(tmp_path / "full")
    bag.open()
    a = bag.add_topic("/a", STRING, [LATCHED])
    b = bag.add_topic("/b", STRING, [LATCHED])
    writer = QueuedBagWriter(bag, max_pending=5)  # not started: nothing drains the queue
    for k, sequence in enumerate([1, 2, 5, 6, 9]):  # gaps of 2 and 2 in the publisher's numbering
        assert writer.try_put(a, T0 + k, T0 + k, sequence, string("a"))
    assert not writer.try_put(b, T0 + 10, T0 + 10, 1, string("b"))
    assert writer.dropped == {b: 1}
    writer.stop()  # never started: drains and closes here
    assert writer.sequence_gaps == {a: 4}
    assert bag.counts == {"/a": 5, "/b": 0}
    assert not writer.try_put(a, T0, T0, 10, string("late"))
    with AnyReader([tmp_path / "full"]) as reader:
        assert sum(c.msgcount for c in reader.connections) == 5


def test_a_topic_with_several_publishers_reports_no_gaps(tmp_path: Path) -> None:
    bag = BagWriter(tmp_path / "several")
    bag.open()
    a = bag.add_topic("/diagnostics", STRING, [LATCHED])
    writer = QueuedBagWriter(bag)
    for k, sequence in enumerate([1, 1, 2, 4, 3]):  # two publishers interleaved
        writer.try_put(a, T0 + k, T0 + k, sequence, string("d"))
    writer.stop()
    assert writer.sequence_gaps == {}
