"""The recorder node: every topic of the suite into a rosbag2-compatible MCAP bag (rh5_bringup.recording).

Chunks are zstd-compressed by default (parameter ``compression``: ``none`` turns it off), in the
writer thread; ``max_bag_size``/``max_bag_duration_s`` split the bag into several MCAP files.

Subscriptions are raw (serialized CDR, never deserialized) with the contract's reliability and
durability and a history of at least ``queue_depth``, so a 1 kHz best-effort stream waits in DDS
while this process is descheduled. No executor runs them: a taker thread takes what arrived every
5 ms (recording.taker: an executor's wake-ups cost half a core at 3 kHz) and only queues ``(topic,
receive time, send time, publisher sequence, bytes)``; a writer thread owns the bag (recording.
queued_writer), so no disk I/O ever delays taking. Log time is rmw's receive timestamp,
publish time the publisher's source timestamp (rosbag2 Jazzy's recv/send timestamps), the MCAP
sequence the publisher's sequence number. SIGINT/SIGTERM: the bag is finished before the summary
(bag path, per-topic received/recorded counts, drops, publisher sequence gaps) is printed.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any, Final

from rclpy.qos import HistoryPolicy, LivelinessPolicy, QoSProfile

from rh5_bringup.recording import BagWriter, OfferedQos, QueuedBagWriter
from rh5_bringup.recording.taker import RawTaker
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import Level, Status, diagnostics_to_msg
from rh5_msgs_py.diagnostic_tasks import Increases, task_status
from rh5_msgs_py.interfaces import Topic, message_class
from rh5_msgs_py.node_runtime import SuiteNode, run_node

__all__ = ["DEFAULT_BAG_ROOT", "RecorderNode", "default_bag_folder", "main", "offered_qos", "recording_qos"]

DEFAULT_BAG_ROOT: Final = Path("out") / "bags"


def default_bag_folder(root: Path = DEFAULT_BAG_ROOT, now: datetime | None = None) -> Path:
    """``<root>/<YYYY-mm-dd_HH-MM-SS>`` (with ``_2``, ``_3``... if taken): where a bag goes by default."""
    stamp = (now or datetime.now()).strftime("%Y-%m-%d_%H-%M-%S")
    candidate, n = root / stamp, 1
    while candidate.exists():
        n += 1
        candidate = root / f"{stamp}_{n}"
    return candidate


def recording_qos(contract: QoSProfile, depth: int) -> QoSProfile:
    """The recorder's subscription QoS: the contract's reliability and durability, a history of >= ``depth``."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(contract.depth, depth),
        reliability=contract.reliability,
        durability=contract.durability,
    )


def offered_qos(profile: QoSProfile) -> OfferedQos:
    """What the suite's publishers of a topic offer (its contract QoS), in rosbag2's metadata terms."""
    liveliness = profile.liveliness
    return OfferedQos(
        reliability=profile.reliability.name.lower(),
        durability=profile.durability.name.lower(),
        history=profile.history.name.lower(),
        depth=profile.depth,
        # rmw applies AUTOMATIC for the system default, and discovery reports it so
        liveliness="automatic" if liveliness == LivelinessPolicy.SYSTEM_DEFAULT else liveliness.name.lower(),
        deadline_ns=profile.deadline.nanoseconds or None,
        lifespan_ns=profile.lifespan.nanoseconds or None,
        liveliness_lease_duration_ns=profile.liveliness_lease_duration.nanoseconds or None,
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


def _never_called(_msg: bytes) -> None:
    """The subscriptions' callback: never run (the taker takes their messages)."""


def _selected_topics(wanted: list[str]) -> list[Topic]:
    unknown = set(wanted) - {t.name for t in interfaces.ALL_TOPICS}
    if unknown:
        msg = f"parameter topics: not topics of the suite: {sorted(unknown)}"
        raise ValueError(msg)
    return [t for t in interfaces.ALL_TOPICS if not wanted or t.name in wanted]


class RecorderNode(SuiteNode):
    """Raw subscriptions to the recorded topics, written to one bag by a :class:`QueuedBagWriter`."""

    def __init__(self) -> None:
        super().__init__(interfaces.RECORDER_NODE, "rh5_bringup", "params/recorder.yaml")
        params = self.params
        topics = _selected_topics(list(params["topics"]))
        output = str(params["output"])
        self.bag_path = (Path(output).expanduser() if output else default_bag_folder()).resolve()
        if self.bag_path.exists():
            msg = f"parameter output: {self.bag_path} exists already (a bag is never overwritten)"
            raise ValueError(msg)
        bag = BagWriter(
            self.bag_path,
            chunk_size=int(params["chunk_size"]),
            chunk_max_age_s=float(params["chunk_max_age_s"]),
            compression="" if params["compression"] == "none" else str(params["compression"]),
            compression_level=int(params["compression_level"]),
            max_bag_size=int(params["max_bag_size"]),
            max_bag_duration_s=float(params["max_bag_duration_s"]),
            custom_data={"recorder": "rh5_bringup/recorder_node"},
        )
        bag.open()
        self._writer = QueuedBagWriter(bag, max_pending=int(params["max_pending"]), name="recorder")
        self._taker = RawTaker(self._deliver, name="recorder-taker")
        self._finished = False
        self._names: dict[int, str] = {}
        try:
            for topic in topics:
                self._record(topic, int(params["queue_depth"]))
        except BaseException:
            self.finish()
            raise
        self._writer.start()
        self._taker.start()
        self._increases = Increases()
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        self.create_wall_timer(
            1.0, lambda: self._publish_diagnostics(diagnostics_to_msg(self.task_statuses(), self.stamp_ns()))
        )
        self.get_logger().info(f"recording {len(topics)} topics to {self.bag_path}")

    def _record(self, topic: Topic, depth: int) -> None:
        """Register ``topic`` in the bag under its fully qualified name and subscribe to it raw, for the taker."""
        topic_id = self._writer.bag.add_topic(self.resolve_topic_name(topic.name), topic.type, [offered_qos(topic.qos)])
        self._names[topic_id] = topic.name
        subscription = self.create_subscription(
            message_class(topic.type),
            topic.name,
            _never_called,
            recording_qos(topic.qos, depth),
            raw=True,
            callback_group=self._taker.callback_group,
        )
        self._taker.add(topic_id, subscription)

    def _deliver(self, topic_id: int, data: bytes, info: dict[str, Any]) -> None:
        """Count and queue one taken message (taker thread)."""
        self.seen[self._names[topic_id]] += 1
        sequence = info["publication_sequence_number"] or 0
        # as rosbag2 records: the log time on the recorder's clock (the simulation's under use_sim_time), the
        # publish time as the sender's middleware stamped it (wall time)
        log_ns = self.stamp_ns() if self.sim_time else info["received_timestamp"]
        self._writer.try_put(topic_id, log_ns, info["source_timestamp"], sequence, data)

    def task_statuses(self) -> list[Status]:
        """``recorder: bag``: ERROR when writing or taking failed, WARN when messages were dropped since the last
        report (the writer's queue was full), else OK."""
        writer = self._writer
        dropped = sum(writer.dropped.values())
        new = int(self._increases("dropped", dropped))
        values = {"bag": str(self.bag_path), "dropped": dropped, "new_dropped": new, "max_pending": writer.high_water}
        error = writer.error or self._taker.error
        if error is not None:
            return [task_status("recorder", "bag", Level.ERROR, "recording failed", {**values, "error": repr(error)})]
        if new:
            return [task_status("recorder", "bag", Level.WARN, "messages dropped", values)]
        return [task_status("recorder", "bag", Level.OK, "recording", values)]

    def finish(self) -> None:
        """Take what arrived, stop taking, write everything queued and close the bag. Idempotent."""
        if not self._finished:
            self._finished = True
            self._taker.stop()
            self._writer.stop()

    def summary(self) -> dict[str, Any]:
        """The base summary plus the bag: finishes it first, so that the counts are final."""
        self.finish()
        writer = self._writer
        counts = writer.bag.counts
        summary = super().summary()
        summary.update(
            bag=str(self.bag_path),
            recorded={self._names[t.channel_id]: counts[t.name] for t in writer.bag.topics},
            dropped={self._names[tid]: n for tid, n in sorted(writer.dropped.items())},
            sequence_gaps={self._names[tid]: n for tid, n in sorted(writer.sequence_gaps.items()) if n},
            max_pending=writer.high_water,
            error=repr(writer.error) if writer.error is not None else None,
            take_error=repr(self._taker.error) if self._taker.error is not None else None,
        )
        return summary

    def destroy_node(self) -> None:
        """Finish the bag, then destroy the node."""
        self.finish()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup recorder_node``."""
    run_node(RecorderNode, args)
