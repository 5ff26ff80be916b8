"""The control cycle's four 1 kHz topics, published from a process of their own.

Publishing a message holds Python's interpreter lock for tens of microseconds (building it and handing it to
DDS), four times a millisecond. In the control process that lock is the cycle's: a publisher thread there
delays the cycle's wake-ups and its steps whenever it runs. So the cycle writes what each cycle measured and
sent as one fixed-size record into a pipe, and a child process (``python -m rh5_bringup.control.stream_publisher``)
publishes ``actuator_states``, ``joint_states``, ``joint_commands`` and ``actuator_commands`` from it, with
the same names, types and QoS, in the control process's namespace.

- A record (header and 4 x 3 x 32 floats, 3.1 kB) is written in one ``write`` below ``PIPE_BUF``, so it
  arrives whole; the pipe buffers ``PIPE_BYTES`` (about 0.3 s of records). The write never blocks: when the
  pipe is full the sample is dropped and counted, as realtime_tools' RealtimePublisher drops one.
- The child publishes every record in order; it counts what it published per topic and writes the counts
  back through a second pipe: first when its publishers exist (the control process waits for that before
  its cycle starts), then once a second and when it ends.
- The child lives as long as the record pipe: it ends when the control process closes it, exits or dies
  (end of file), after publishing what is left. It ignores SIGINT (a Ctrl-C reaches the whole process
  group; the control process decides when publishing ends).
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import Any, Final

import numpy as np

from rh5_msgs_py import interfaces
from rh5_msgs_py.diagnostic_keys import ControlKeys
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES, NUM_ACTUATORS, NUM_JOINTS

__all__ = ["STREAMS", "StreamPublisherProcess", "main"]

STREAMS: Final = (
    interfaces.ACTUATOR_STATES,
    interfaces.JOINT_STATES,
    interfaces.JOINT_COMMANDS,
    interfaces.ACTUATOR_COMMANDS,
)
"""The topics, in the record's order (CycleSample's order)."""
_NAMES: Final = (ACTUATOR_NAMES, JOINT_NAMES, JOINT_NAMES, ACTUATOR_NAMES)
_WIDTH: Final = NUM_JOINTS
assert NUM_ACTUATORS == NUM_JOINTS  # one width for every stream
_HEADER: Final = 4  # int64: sequence, stamp_ns, presence mask, spare
RECORD_BYTES: Final = 8 * (_HEADER + len(STREAMS) * 3 * _WIDTH)
assert RECORD_BYTES <= select.PIPE_BUF  # one write is one whole record
PIPE_BYTES: Final = 1 << 20
"""Record pipe capacity asked for (Linux ``F_SETPIPE_SZ``): ~330 records, a third of a second at 1 kHz."""
_F_SETPIPE_SZ: Final = 1031
COUNTS_PERIOD_S: Final = 1.0
READY_TIMEOUT_S: Final = 10.0
"""How long the control process waits for the child's publishers (a cold interpreter imports rclpy first)."""
EXIT_GRACE_S: Final = 3.0

Triple = tuple[np.ndarray, np.ndarray | None, np.ndarray | None]


def _record() -> tuple[np.ndarray, np.ndarray, memoryview]:
    """One record's buffer: its int64 header view, its (stream, field, value) view and its bytes."""
    record = np.zeros(_HEADER + len(STREAMS) * 3 * _WIDTH)
    values = record[_HEADER:].reshape(len(STREAMS), 3, _WIDTH)
    return record[:_HEADER].view(np.int64), values, memoryview(record).cast("B")


class StreamPublisherProcess:
    """The control process's side: starts the child, hands it each cycle's sample, reads back its counts."""

    def __init__(self, namespace: str = "/", node_name: str = interfaces.CONTROL_STREAMS_NODE) -> None:
        record_read, self._record_write = os.pipe()
        counts_read, counts_write = os.pipe()
        with contextlib.suppress(OSError):  # a smaller default pipe only drops samples sooner
            fcntl.fcntl(self._record_write, _F_SETPIPE_SZ, PIPE_BYTES)
        os.set_blocking(self._record_write, False)
        os.set_blocking(counts_read, False)
        self._counts_read = counts_read
        self._header, self._values, self._bytes = _record()
        self.sequence = 0
        self.dropped = 0
        """Samples not handed over because the child was behind by a full pipe (or gone)."""
        self.published: dict[str, int] = {topic.name: 0 for topic in STREAMS}
        """What the child reported published per topic (its latest report)."""
        self.error: str | None = None
        self._pending = b""
        self._reported = False
        command = [sys.executable, "-m", "rh5_bringup.control.stream_publisher", str(record_read), str(counts_write)]
        command += ["--ros-args", "-r", f"__node:={node_name}", "-r", f"__ns:={namespace or '/'}"]
        try:
            self.process = subprocess.Popen(command, pass_fds=(record_read, counts_write), stdin=subprocess.DEVNULL)
        finally:
            os.close(record_read)
            os.close(counts_write)

    def send(self, stamp_ns: int, streams: Sequence[Triple | None]) -> bool:
        """Hand one cycle's streams over (None: not this cycle) without blocking; False when dropped."""
        if self._record_write < 0:
            self.dropped += 1
            return False
        mask = 0
        values = self._values
        for k, triple in enumerate(streams):
            if triple is None:
                continue
            for f, array in enumerate(triple):
                if array is not None:
                    values[k, f] = array
                    mask |= 1 << (3 * k + f)
        self.sequence += 1
        header = self._header
        header[0], header[1], header[2] = self.sequence, stamp_ns, mask
        try:
            os.write(self._record_write, self._bytes)
        except BlockingIOError:
            self.dropped += 1
            return False
        except OSError as err:  # the child is gone (EPIPE): the cycle goes on without its topics
            self.error = f"stream publisher gone: {err}"
            self.dropped += 1
            return False
        return True

    def wait_ready(self, timeout_s: float = READY_TIMEOUT_S) -> bool:
        """Wait until the child has its publishers (its first report); False if it did not within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not self._reported and self.alive and (left := deadline - time.monotonic()) > 0:
            select.select([self._counts_read], [], [], left)
            self.poll_counts()
        return self._reported

    def poll_counts(self) -> dict[str, int]:
        """Read what the child reported since the last call (never blocks); returns the latest counts."""
        try:
            while chunk := os.read(self._counts_read, 65536):
                self._pending += chunk
        except BlockingIOError:
            pass
        except OSError:
            return self.published
        *lines, self._pending = self._pending.split(b"\n")
        if lines and lines[-1]:
            self.published = {**self.published, **json.loads(lines[-1])}
            self._reported = True
        return self.published

    @property
    def alive(self) -> bool:
        """Whether the child still runs."""
        return self.process.poll() is None

    def close(self, timeout_s: float = EXIT_GRACE_S) -> dict[str, int]:
        """End the child (it publishes what is queued first) and return its final counts. Idempotent."""
        if self._record_write >= 0:
            os.close(self._record_write)
            self._record_write = -1
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        counts = self.poll_counts()
        if self._counts_read >= 0:
            os.close(self._counts_read)
            self._counts_read = -1
        return counts

    def diagnostics(self) -> dict[str, object]:
        """``streams.*`` values for /diagnostics."""
        counts = self.poll_counts()
        values: dict[str, object] = {"streams.handed_over": self.sequence, ControlKeys.STREAMS_DROPPED: self.dropped}
        values.update({f"streams.published.{name}": n for name, n in counts.items()})
        values["streams.process_alive"] = self.alive
        if self.error is not None:
            values["streams.error"] = self.error
        return values


def _publish_forever(record_fd: int, counts_fd: int, node: Any) -> dict[str, int]:
    """The child's loop: publish every record until end of file; report counts once a second and at the end."""
    from rh5_msgs_py.conversions import JointStateCodec  # noqa: PLC0415

    publishers = [node.create_publisher(interfaces.message_class(t.type), t.name, t.qos) for t in STREAMS]
    codecs = [JointStateCodec(names) for names in _NAMES]
    counts = {topic.name: 0 for topic in STREAMS}
    names = [topic.name for topic in STREAMS]
    header, values, buffer = _record()
    reported_at = time.monotonic()
    os.set_blocking(counts_fd, False)  # a report the control process has not read yet is dropped, never waited for

    def report() -> None:
        with contextlib.suppress(OSError):
            os.write(counts_fd, (json.dumps(counts) + "\n").encode())

    report()  # the first report says the publishers exist

    while True:
        got = 0
        while got < RECORD_BYTES:  # a record arrives whole; the loop only guards against a short read
            n = os.readv(record_fd, [buffer[got:]])
            if n == 0:
                report()
                return counts
            got += n
        stamp, mask = int(header[1]), int(header[2])
        for k in range(len(STREAMS)):
            if not mask & (1 << (3 * k)):
                continue
            velocity = values[k, 1] if mask & (1 << (3 * k + 1)) else None
            effort = values[k, 2] if mask & (1 << (3 * k + 2)) else None
            publishers[k].publish(codecs[k].encode_serialized(values[k, 0], velocity, effort, stamp_ns=stamp))
            counts[names[k]] += 1
        if time.monotonic() - reported_at >= COUNTS_PERIOD_S:
            reported_at = time.monotonic()
            report()


def main(argv: list[str] | None = None) -> None:
    """The child's entry point: ``python -m rh5_bringup.control.stream_publisher RECORD_FD COUNTS_FD [--ros-args]``."""
    import rclpy  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

    args = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("record_fd", type=int)
    parser.add_argument("counts_fd", type=int)
    ours = args[: args.index("--ros-args")] if "--ros-args" in args else args
    options = parser.parse_args(ours)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the control process ends publishing by closing the pipe
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))  # leave through ``finally``: DDS removes its files
    rclpy.init(args=["stream_publisher", *args[len(ours) :]], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(interfaces.CONTROL_STREAMS_NODE, start_parameter_services=False)
    try:
        _publish_forever(options.record_fd, options.counts_fd, node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
