"""Read a recorded rosbag2 folder (MCAP, CDR) into numpy arrays, one record per topic of the suite.

Topics are found by their contract name (rh5_msgs_py.interfaces) at the end of the recorded name, so
``/joint_states`` and ``/rh5/joint_states`` both match. Times are seconds since the bag's first
message: the header stamps where the publisher set them on the recorder's clock (sender time, free of
recording latency), else the time the recorder received the message. With a simulation clock (/clock) the
times are simulated time: a bag recorded on wall time is moved onto it, one recorded on simulated time
(use_sim_time) already is, and then the MCAP records' publish times give the streams their wall-clock times.
The 1 kHz streams are decoded in batches by rh5_bringup.analysis.cdr; the few other messages go through rosbags'
deserializer.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Final

import numpy as np
import yaml
from mcap.reader import make_reader
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader, AnyReaderError

from rh5_bringup.analysis.cdr import CdrError, decode_joint_states, decode_stamped_floats
from rh5_bringup.analysis.records import (
    BoolSeries,
    DiagnosticRecord,
    JointSeries,
    NotABagError,
    PlannedBase,
    PlannedJoints,
    PoseSeries,
    Recording,
    WrenchSeries,
)
from rh5_msgs_py import interfaces
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.conversions import time_to_ns
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES

BATCH: Final = 8192
"""Messages decoded per batch: bounds the raw bytes held in memory (~11 MB for 32-joint JointStates)."""
STAMP_TOLERANCE_NS: Final = 5_000_000_000
"""Header stamps within this of the receive times (median) are on the recorder's clock and are used."""
SIM_CLOCK_TOLERANCE_NS: Final = 1_000_000_000
"""/clock logged within this of the time it carries (median): the bag was recorded on simulated time."""


# --- finding the suite's topics in the bag ----------------------------------------------------------------------------


def _match_score(recorded: str, contract: str) -> int:
    """2 for the exact (absolute) name, 1 for a namespaced one, 0 for another topic."""
    name = contract.lstrip("/")
    if recorded.lstrip("/") == name:
        return 2
    return 1 if recorded.endswith("/" + name) else 0


def find_connections(connections: Iterable[Any], contract: interfaces.Topic) -> list[Any]:
    """The bag's connections of a contract topic (best name match only, right type only)."""
    scored = [(_match_score(c.topic, contract.name), c) for c in connections if c.msgtype == contract.type]
    best = max((s for s, _ in scored), default=0)
    return [c for s, c in scored if s == best and best > 0]


# --- times -----------------------------------------------------------------------------------------------------------


def pick_times(stamps_ns: NDArray[np.int64], log_ns: NDArray[np.int64]) -> tuple[NDArray[np.int64], str]:
    """Header stamps if every one is set and they sit on the recorder's clock, else the receive times.

    A zero stamp logged at zero is set: on simulated time the first sample is taken at t = 0 (the simulation's
    base pose), and reading it as unset put the whole stream on receive times, which lag by up to a /clock tick.
    """
    stamp_set = (stamps_ns > 0) | ((stamps_ns == 0) & (log_ns < STAMP_TOLERANCE_NS))
    set_everywhere = bool(len(stamps_ns)) and bool(stamp_set.all())
    if set_everywhere and np.median(np.abs(stamps_ns - log_ns)) < STAMP_TOLERANCE_NS:
        return stamps_ns, "header"
    return log_ns, "receive"


def _seconds(ns: NDArray[np.int64], origin_ns: int) -> FloatArray:
    return (ns - origin_ns).astype(np.float64) / 1e9


# --- accumulators: raw messages in, arrays out --------------------------------------------------------------------


class _Batches:
    """Collects raw messages with receive times and decodes them every BATCH messages."""

    def __init__(self, decode: Callable[[list[bytes]], Any]) -> None:
        self._decode = decode
        self._raws: list[bytes] = []
        self._log: list[int] = []
        self._publish: list[int] = []
        self.decoded: list[tuple[Any, NDArray[np.int64]]] = []
        self.publish_ns: list[NDArray[np.int64]] = []

    def add(self, raw: bytes, log_ns: int, publish_ns: int) -> None:
        self._raws.append(raw)
        self._log.append(log_ns)
        self._publish.append(publish_ns)
        if len(self._raws) >= BATCH:
            self.flush()

    def flush(self) -> None:
        if self._raws:
            self.decoded.append((self._decode(self._raws), np.asarray(self._log, dtype=np.int64)))
            self.publish_ns.append(np.asarray(self._publish, dtype=np.int64))
            self._raws, self._log, self._publish = [], [], []

    def publish_times(self, order: NDArray[np.intp] | None) -> NDArray[np.int64]:
        """The publish times of every message added, in ``order`` (None: as added)."""
        ns = np.concatenate(self.publish_ns) if self.publish_ns else np.zeros(0, dtype=np.int64)
        return ns if order is None else ns[order]


def _column_order(blocks: Iterable[Sequence[str]], contract: Sequence[str]) -> tuple[str, ...]:
    seen: dict[str, None] = {}
    for names in blocks:
        seen.update(dict.fromkeys(names))
    if set(seen) <= set(contract):
        return tuple(n for n in contract if n in seen)
    return tuple(seen)


def _joint_series(topic: str, batches: _Batches, contract: Sequence[str], origin_ns: int) -> JointSeries | None:
    batches.flush()
    names = _column_order([b.names for blocks, _ in batches.decoded for b in blocks], contract)
    total = sum(len(log) for _, log in batches.decoded)
    if total == 0:
        return None
    arrays = {f: np.full((total, len(names)), np.nan) for f in ("position", "velocity", "effort")}
    stamps = np.zeros(total, dtype=np.int64)
    log_ns = np.concatenate([log for _, log in batches.decoded])
    column = {n: i for i, n in enumerate(names)}
    start = 0
    while batches.decoded:  # release each batch once copied: peak memory stays near one copy of the stream
        blocks, log = batches.decoded.pop(0)
        for block in blocks:
            rows = start + block.rows
            stamps[rows] = block.stamps_ns
            cols = np.array([column[n] for n in block.names], dtype=np.intp)
            every_column = len(cols) == len(names) and bool((cols == np.arange(len(names))).all())
            for f, out in arrays.items():
                values = getattr(block, f)
                if values is None or not len(cols) or values.shape[1] != len(cols):
                    continue
                if every_column:
                    out[rows] = values
                else:
                    out[rows[:, None], cols[None, :]] = values
        start += len(log)
    ns, source = pick_times(stamps, log_ns)
    order = None
    if len(ns) > 1 and not bool((np.diff(ns) >= 0).all()):
        order = np.argsort(ns, kind="stable")
        ns = ns[order]
        arrays = {f: a[order] for f, a in arrays.items()}
    return JointSeries(
        topic,
        names,
        _seconds(ns, origin_ns),
        arrays["position"],
        arrays["velocity"],
        arrays["effort"],
        source,
        publish_ns=batches.publish_times(order),
    )


def _stamped(batches: _Batches, origin_ns: int) -> tuple[FloatArray, FloatArray, str, NDArray[np.int64]] | None:
    """Times, values, the time source and the publish times of a stamped stream, in time order."""
    batches.flush()
    if not batches.decoded:
        return None
    stamps = np.concatenate([d[0] for d, _ in batches.decoded])
    values = np.concatenate([d[1] for d, _ in batches.decoded])
    log_ns = np.concatenate([log for _, log in batches.decoded])
    ns, source = pick_times(stamps, log_ns)
    order = np.argsort(ns, kind="stable")
    return _seconds(ns[order], origin_ns), values[order], source, batches.publish_times(order)


# --- the few low-rate messages (rosbags objects) --------------------------------------------------------------------


def _duration_s(d: Any) -> float:
    return d.sec + d.nanosec * 1e-9


def _planned_joints(msg: Any, t: float) -> PlannedJoints:
    points = msg.points
    names = tuple(msg.joint_names)
    times = np.array([_duration_s(p.time_from_start) for p in points], dtype=np.float64)
    positions = np.stack([p.positions for p in points]) if points else np.zeros((0, len(names)))
    velocities = None
    if points and all(len(p.velocities) == len(names) for p in points):
        velocities = np.stack([p.velocities for p in points]).astype(np.float64)
    return PlannedJoints(t, names, times, positions.astype(np.float64), velocities)


def _planned_base(msg: Any, t: float) -> PlannedBase:
    points = [p for p in msg.points if p.transforms]
    times = np.array([_duration_s(p.time_from_start) for p in points], dtype=np.float64)
    tf = [p.transforms[0] for p in points]
    positions = np.array([(x.translation.x, x.translation.y, x.translation.z) for x in tf], dtype=np.float64)
    quats = np.array([(x.rotation.x, x.rotation.y, x.rotation.z, x.rotation.w) for x in tf], dtype=np.float64)
    return PlannedBase(t, times, positions.reshape(-1, 3), quats.reshape(-1, 4))


def _stamp_or_log(header: Any, log_ns: int) -> int:
    """One low-rate message's time, by ``pick_times``'s rule."""
    ns, _ = pick_times(np.array([time_to_ns(header.stamp)], dtype=np.int64), np.array([log_ns], dtype=np.int64))
    return int(ns[0])


def _diagnostics(msg: Any, log_ns: int, origin_ns: int) -> list[DiagnosticRecord]:
    t = (_stamp_or_log(msg.header, log_ns) - origin_ns) / 1e9
    return [
        DiagnosticRecord(t, s.name, int(s.level), s.message, {kv.key: kv.value for kv in s.values}) for s in msg.status
    ]


def deserialize(reader: AnyReader, raw: bytes, typename: str) -> Any:
    """rosbags' CDR deserializer, tolerating bytes after the message's end.

    rclpy.serialization.serialize_message returns a buffer longer than the encoding (the estimated
    size); rosbags refuses more than 3 such bytes, the content before them is still a whole message.
    """
    try:
        return reader.deserialize(raw, typename)
    except AnyReaderError as err:
        if "size mismatch" not in str(err):
            raise
    msgdef = reader.typestore.get_msgdef(typename)
    decode = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    message, _ = decode(memoryview(raw)[4:], 0, msgdef.cls, reader.typestore)
    return message


# --- the bag ---------------------------------------------------------------------------------------------------------

_JOINT_STREAMS: Final = {
    "joint_commands": (interfaces.JOINT_COMMANDS, JOINT_NAMES),
    "joint_states": (interfaces.JOINT_STATES, JOINT_NAMES),
    "actuator_commands": (interfaces.ACTUATOR_COMMANDS, ACTUATOR_NAMES),
    "actuator_states": (interfaces.ACTUATOR_STATES, ACTUATOR_NAMES),
}
_FLOAT_STREAMS: Final = {
    "base_pose": (interfaces.SIM_BASE_POSE, 7),
    "wrench_left": (interfaces.SIM_WRENCH_LEFT, 6),
    "wrench_right": (interfaces.SIM_WRENCH_RIGHT, 6),
}
_OBJECT_TOPICS: Final = {
    "planned_joints": interfaces.PLANNED_TRAJECTORY,
    "planned_base": interfaces.PLANNED_BASE_TRAJECTORY,
    "diagnostics": interfaces.DIAGNOSTICS,
    "estopped": interfaces.DRIVER_ESTOP,
    "clock": interfaces.CLOCK,
}


def open_bag(bag: Path) -> AnyReader:
    """An opened AnyReader for a rosbag2 folder; NotABagError with the reason otherwise."""
    bag = Path(bag)
    if not bag.is_dir() or not (bag / "metadata.yaml").is_file():
        what = "does not exist" if not bag.exists() else "has no metadata.yaml"
        msg = f"{bag} is not a rosbag2 folder: it {what}"
        raise NotABagError(msg)
    reader = AnyReader([bag])
    try:
        reader.open()
    except (AnyReaderError, FileNotFoundError, OSError, ValueError, KeyError) as err:
        msg = f"{bag} is not a readable rosbag2 folder: {err}"
        raise NotABagError(msg) from err
    return reader


def load_recording(bag: Path) -> Recording:
    """Read the suite's topics of ``bag`` into a Recording (NotABagError if it cannot be read)."""
    bag = Path(bag)
    reader = open_bag(bag)
    try:
        return _read(reader, bag)
    except (AnyReaderError, CdrError) as err:
        msg = f"{bag}: cannot decode the recording: {err}"
        raise NotABagError(msg) from err
    finally:
        reader.close()


def _read(reader: AnyReader, bag: Path) -> Recording:
    origin = int(reader.start_time) if reader.message_count else 0
    rec = Recording(
        bag,
        origin,
        reader.duration / 1e9 if reader.message_count else 0.0,
        {c.topic: c.msgcount for c in reader.connections},
    )
    route: dict[int, tuple[str, Any]] = {}
    joint_batches = {key: _Batches(decode_joint_states) for key in _JOINT_STREAMS}
    float_batches = {
        key: _Batches(lambda raws, n=n: decode_stamped_floats(raws, n)) for key, (_, n) in _FLOAT_STREAMS.items()
    }
    for key, (topic, _) in _JOINT_STREAMS.items():
        route.update({c.id: ("joint", key) for c in find_connections(reader.connections, topic)})
    for key, (topic, _) in _FLOAT_STREAMS.items():
        route.update({c.id: ("float", key) for c in find_connections(reader.connections, topic)})
    for key, topic in _OBJECT_TOPICS.items():
        route.update({c.id: ("object", key) for c in find_connections(reader.connections, topic)})
    estop_t: list[int] = []
    estop_v: list[bool] = []
    clock_log: list[int] = []
    clock_sim: list[int] = []
    wanted = [c for c in reader.connections if c.id in route]
    names: dict[str, str] = {}
    clock_publish: list[int] = []
    for connection, log_ns, publish_ns, raw in _messages(reader, bag, wanted):
        kind, key = route[connection.id]
        names.setdefault(key, connection.topic)
        if kind == "joint":
            joint_batches[key].add(raw, log_ns, publish_ns)
        elif kind == "float":
            float_batches[key].add(raw, log_ns, publish_ns)
        else:
            msg = deserialize(reader, raw, connection.msgtype)
            t = (log_ns - origin) / 1e9
            if key == "planned_joints":
                rec.planned_joints.append(_planned_joints(msg, t))
            elif key == "planned_base":
                rec.planned_base.append(_planned_base(msg, t))
            elif key == "diagnostics":
                rec.diagnostics.extend(_diagnostics(msg, log_ns, origin))
            elif key == "clock":
                clock_log.append(log_ns)
                clock_publish.append(publish_ns)
                clock_sim.append(time_to_ns(msg.clock))
            else:
                estop_t.append(log_ns)
                estop_v.append(bool(msg.data))
    for key, (_, contract) in _JOINT_STREAMS.items():
        setattr(rec, key, _joint_series(names.get(key, key), joint_batches[key], contract, origin))
    for key in _FLOAT_STREAMS:
        data = _stamped(float_batches[key], origin)
        if data is None:
            continue
        t, values, source, publish_ns = data
        if key == "base_pose":
            rec.base_pose = PoseSeries(names[key], t, values[:, :3], values[:, 3:], source, publish_ns=publish_ns)
        else:
            setattr(rec, key, WrenchSeries(names[key], t, values[:, :3], values[:, 3:], source))
    if estop_t:
        rec.estopped = BoolSeries(names["estopped"], _seconds(np.asarray(estop_t), origin), np.asarray(estop_v))
    rec.diagnostics.sort(key=lambda d: d.t)
    if len(clock_log) < 2:
        return rec
    clock_t, clock_ns = _seconds(np.asarray(clock_log), origin), np.asarray(clock_sim, dtype=np.int64)
    if recorded_on_simulated_time(np.asarray(clock_log, dtype=np.int64), clock_ns):
        return with_wall_times(rec, clock_t, np.asarray(clock_publish, dtype=np.int64), clock_ns)
    return on_simulated_time(rec, clock_t, clock_ns)


def _messages(reader: AnyReader, bag: Path, wanted: list[Any]) -> Iterator[tuple[Any, int, int, bytes]]:
    """(connection, log time, publish time, raw message) of the ``wanted`` connections in time order.

    rosbags gives log times only; for an MCAP bag the publish times (when the sender's middleware published:
    wall clock, also in a bag recorded on simulated time) come from the MCAP records themselves.
    """
    info = yaml.safe_load((bag / "metadata.yaml").read_text(encoding="utf-8")).get("rosbag2_bagfile_information", {})
    files = [bag / name for name in info.get("relative_file_paths", [])]
    mcap = info.get("storage_identifier") == "mcap" and info.get("compression_mode", "") in {"", "NONE"}
    if not mcap or not all(_indexed(path) for path in files):  # rosbags alone (a file without its summary)
        for connection, log_ns, raw in reader.messages(connections=wanted):
            yield connection, log_ns, log_ns, raw
        return
    by_channel = {(c.topic, c.msgtype): c for c in wanted}
    topics = sorted({c.topic for c in wanted})
    for path in files:
        with path.open("rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages(topics=topics, log_time_order=True):
                connection = by_channel.get((channel.topic, schema.name if schema is not None else ""))
                if connection is not None:
                    yield connection, message.log_time, message.publish_time, message.data


def _indexed(path: Path) -> bool:
    """Whether an MCAP file has its summary (chunk indexes), so that its messages can be read in time order."""
    try:
        with path.open("rb") as stream:
            return make_reader(stream).get_summary() is not None
    except Exception:  # any unreadable file: rosbags decides and reports
        return False


def recorded_on_simulated_time(clock_log_ns: NDArray[np.int64], clock_ns: NDArray[np.int64]) -> bool:
    """Whether the recorder ran on the simulation's clock (use_sim_time): /clock logged at the times it carries."""
    return bool(np.median(np.abs(clock_log_ns - clock_ns)) < SIM_CLOCK_TOLERANCE_NS)


def with_wall_times(
    rec: Recording, clock_t: FloatArray, clock_publish_ns: NDArray[np.int64], clock_ns: NDArray[np.int64]
) -> Recording:
    """``rec`` of a bag recorded on simulated time: its times stay; the streams get their wall-clock times from
    the publish times (stream rates are measured on the clock the loops ran on) and the simulation's speed
    comes from /clock's simulated against its publish times."""
    wall = (clock_publish_ns[-1] - clock_publish_ns[0]) / 1e9
    speed = (clock_ns[-1] - clock_ns[0]) / 1e9 / max(wall, 1e-9)
    out = replace(
        rec,
        notes=[
            *rec.notes,
            f"times are simulated time (recorded on /clock, {len(clock_t)} messages): the simulation ran at "
            f"{speed:.2f} x real time",
        ],
        sim_speed=float(speed),
    )
    for key in ("joint_commands", "joint_states", "actuator_commands", "actuator_states", "base_pose"):
        series = getattr(rec, key)
        if series is not None and series.publish_ns is not None and len(series.publish_ns) == len(series.t):
            wall_t = (series.publish_ns - clock_publish_ns[0]) / 1e9 + clock_t[0]
            setattr(out, key, replace(series, wall_t=wall_t))
    return out


def on_simulated_time(rec: Recording, clock_t: FloatArray, clock_ns: NDArray[np.int64]) -> Recording:
    """``rec`` with every time axis moved from the recorder's clock onto the simulation's (/clock).

    A simulation slower than real time plays the plan on its own clock (the stabilizer follows /clock), so
    plan and measurement only line up there. Each /clock message maps its receive time to the simulated time;
    times in between are interpolated, times before the first and after the last move at the wall clock's
    rate. The bag's start keeps time 0 (the simulated time is offset to the first clock message's receive time).
    """
    sim = (clock_ns - clock_ns[0]) / 1e9 + clock_t[0]
    speed = (sim[-1] - sim[0]) / max(clock_t[-1] - clock_t[0], 1e-9)

    def remap(t: FloatArray) -> FloatArray:
        t = np.asarray(t, dtype=np.float64)
        out = np.interp(t, clock_t, sim)
        before, after = t < clock_t[0], t > clock_t[-1]
        out[before] = t[before]
        out[after] = sim[-1] + (t[after] - clock_t[-1])
        return out

    def at(t: float) -> float:
        return float(remap(np.array([t]))[0])

    out = replace(
        rec,
        duration_s=at(rec.duration_s),
        planned_joints=[replace(p, t=at(p.t)) for p in rec.planned_joints],
        planned_base=[replace(p, t=at(p.t)) for p in rec.planned_base],
        diagnostics=[replace(d, t=at(d.t)) for d in rec.diagnostics],
        notes=[
            *rec.notes,
            f"times are simulated time (/clock, {len(clock_t)} messages): the simulation ran at "
            f"{speed:.2f} x real time",
        ],
        sim_speed=float(speed),
    )
    timed = ("joint_commands", "joint_states", "actuator_commands", "actuator_states", "base_pose")
    for key in timed:  # their stream rates stay measurable on the clock the loops ran on
        series = getattr(rec, key)
        if series is not None:
            setattr(out, key, replace(series, t=remap(series.t), wall_t=series.t))
    for key in ("wrench_left", "wrench_right", "estopped"):
        series = getattr(rec, key)
        if series is not None:
            setattr(out, key, replace(series, t=remap(series.t)))
    return out
