"""Transports: UDP on 127.0.0.1 both ways, CAN over python-can's virtual bus with interleaved senders, lifecycle,
timeouts, filtering and the lazy factory. Network traffic stays on 127.0.0.1."""

from __future__ import annotations

import gc
import logging
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator

import can
import pytest

from rh5_bringup.hardware.ndlcom.codec import BROADCAST, Frame, FrameEncoder, encode_frame
from rh5_bringup.hardware.transports import (
    TRANSPORTS,
    Transport,
    TransportInitError,
    TransportOperationError,
    TransportTimeoutError,
    open_transport,
    transport_class,
)
from rh5_bringup.hardware.transports.can import DEFAULT_BASE_ID, CanTransport, can_messages, frame_sender
from rh5_bringup.hardware.transports.udp import UdpTransport

PC, KNEE, HIP = 0x01, 0x43, 0x42
LOCAL = ("127.0.0.1", 0)


@pytest.fixture
def udp_pair() -> Iterator[tuple[UdpTransport, UdpTransport]]:
    """The driver's side (PC) and a router side that answers whoever wrote last."""
    router = UdpTransport(LOCAL)
    pc = UdpTransport(LOCAL, remote=router.local_address)
    yield pc, router
    pc.shutdown()
    router.shutdown()


@pytest.fixture
def channel() -> str:
    """A fresh python-can virtual channel name per test (virtual buses of equal names share traffic)."""
    return f"rh5-test-{uuid.uuid4().hex[:8]}"


def _collect(transport: Transport, count: int, timeout: float = 2.0) -> list[Frame]:
    return transport.recv_frames(count, timeout)


# --------------------------------------------------------------------------------------------------- UDP


def test_udp_exchanges_frames_both_ways(udp_pair: tuple[UdpTransport, UdpTransport]) -> None:
    pc, router = udp_pair
    pc_side, board_side = FrameEncoder(PC), FrameEncoder(KNEE)
    pc.send_frame(pc_side.encode(KNEE, b"command"))
    assert _collect(router, 1) == [Frame(KNEE, PC, 0, b"command")]
    router.send_frame(board_side.encode(PC, b"telemetry"))  # to the peer it heard from
    assert _collect(pc, 1) == [Frame(PC, KNEE, 0, b"telemetry")]
    assert router.remote == pc.local_address
    stats = pc.stats()
    assert (stats.sent_frames, stats.received_chunks) == (1, 1)
    assert stats.decoder.senders[KNEE].frames == 1


def test_udp_packs_many_frames_per_datagram_within_the_limit() -> None:
    with UdpTransport(LOCAL) as router, UdpTransport(LOCAL, remote=router.local_address, max_datagram=600) as pc:
        frames = [encode_frame(KNEE, PC, i, bytes(40)) for i in range(32)]  # 48 bytes each on the wire
        pc.send_frames(frames)
        received = _collect(router, 32)
        assert [f.counter for f in received] == list(range(32))
        assert pc.stats().sent_chunks == 3  # 12 + 12 + 8 frames of 48 bytes in <= 600-byte datagrams
        assert router.stats().received_chunks == 3
        assert router.stats().decoder.senders[PC].lost == 0


def test_udp_receive_filter_drops_frames_for_others_but_keeps_broadcast() -> None:
    with UdpTransport(LOCAL, receivers=[PC]) as pc, UdpTransport(LOCAL, remote=pc.local_address) as board:
        board.send_frames([encode_frame(0x77, KNEE, 0, b"a"), encode_frame(BROADCAST, KNEE, 0, b"b")])
        board.send_frame(encode_frame(PC, KNEE, 0, b"c"))
        received = _collect(pc, 2)
        assert [f.payload for f in received] == [b"b", b"c"]
        assert pc.stats().filtered_frames == 1
    with pytest.raises(ValueError, match=r"outside 0\.\.255"):
        UdpTransport(LOCAL, receivers=[256])


def test_udp_without_remote_cannot_send_before_hearing_from_a_peer() -> None:
    with UdpTransport(LOCAL) as router:
        assert router.remote is None
        with pytest.raises(TransportOperationError, match="no remote"):
            router.send_frame(encode_frame(PC, KNEE, 0, b""))


def test_udp_bind_failure_is_an_init_error_from_os_error() -> None:
    with UdpTransport(LOCAL) as first:
        with pytest.raises(TransportInitError, match="cannot bind UDP socket") as info:
            UdpTransport(first.local_address)
        assert isinstance(info.value.__cause__, OSError)
    with pytest.raises(ValueError, match="max_datagram"):
        UdpTransport(LOCAL, max_datagram=100)


def test_recv_times_out_with_nothing_and_recv_frames_raises(udp_pair: tuple[UdpTransport, UdpTransport]) -> None:
    pc, router = udp_pair
    start = time.monotonic()
    assert pc.recv(0.05) == []
    assert 0.04 <= time.monotonic() - start < 1.0
    assert pc.recv(0.0) == []
    pc.send_frame(encode_frame(KNEE, PC, 0, b"x"))
    with pytest.raises(TransportTimeoutError, match=r"1 of 2 frames within 0\.1 s") as info:
        router.recv_frames(2, 0.1)
    assert isinstance(info.value, TimeoutError)
    assert info.value.frames == [Frame(KNEE, PC, 0, b"x")]


def test_recv_keeps_waiting_through_garbage_until_the_timeout(udp_pair: tuple[UdpTransport, UdpTransport]) -> None:
    pc, router = udp_pair
    pc._send_bytes(b"\x7e\x01\x02garbage\x7e")  # a datagram without any good frame
    pc.send_frame(encode_frame(KNEE, PC, 0, b"ok"))
    assert _collect(router, 1) == [Frame(KNEE, PC, 0, b"ok")]
    assert router.stats().decoder.senders[0x02].crc_errors == 1


def test_shutdown_is_idempotent_and_closes_the_link(udp_pair: tuple[UdpTransport, UdpTransport]) -> None:
    pc, _ = udp_pair
    assert not pc.is_shutdown
    pc.shutdown()
    pc.shutdown()
    assert pc.is_shutdown
    with pytest.raises(TransportOperationError, match="shut down"):
        pc.send_frame(encode_frame(KNEE, PC, 0, b""))
    with pytest.raises(TransportOperationError, match="shut down"):
        pc.recv(0.0)
    assert "shut down" in repr(pc)


def test_context_manager_shuts_down() -> None:
    with UdpTransport(LOCAL) as transport:
        assert not transport.is_shutdown
    assert transport.is_shutdown


def test_forgotten_transport_warns_and_cleans_up(caplog: pytest.LogCaptureFixture) -> None:
    transport = UdpTransport(LOCAL)
    sock = transport._sock
    with caplog.at_level(logging.WARNING, logger="rh5_bringup.hardware.transports.base"):
        del transport
        gc.collect()
    assert "UdpTransport was not properly shut down" in caplog.text
    assert sock.fileno() == -1


def test_failed_constructor_leaves_nothing_to_shut_down() -> None:
    class Broken(Transport):
        def __init__(self) -> None:
            raise TransportInitError("no hardware")

        def _recv_bytes(self, timeout: float | None) -> None:
            del timeout

        def _send_bytes(self, data: bytes) -> None:
            pass

    with pytest.raises(TransportInitError):
        Broken()
    gc.collect()  # __del__ of the half-built instance must not raise or warn


# --------------------------------------------------------------------------------------------------- CAN


def test_can_round_trip_both_ways_over_the_virtual_bus(channel: str) -> None:
    with CanTransport("virtual", channel, receivers=[PC]) as pc, CanTransport("virtual", channel) as board:
        pc.send_frame(encode_frame(KNEE, PC, 0, bytes(range(20))))
        assert _collect(board, 1) == [Frame(KNEE, PC, 0, bytes(range(20)))]
        board.send_frames([encode_frame(PC, KNEE, i, bytes([0x7E, 0x7D]) * 20) for i in range(3)])
        received = _collect(pc, 3)
        assert received == [Frame(PC, KNEE, i, bytes([0x7E, 0x7D]) * 20) for i in range(3)]
        assert pc.stats().decoder.senders[KNEE].frames == 3


def test_can_reassembles_interleaved_senders(channel: str) -> None:
    """Two boards' frames cut into CAN frames and interleaved one by one still decode, in per-sender order."""
    knee = [encode_frame(PC, KNEE, i, bytes([i]) * 40) for i in range(4)]
    hip = [encode_frame(PC, HIP, i, bytes([0x7E, i]) * 20) for i in range(4)]
    knee_messages = [m for f in knee for m in can_messages(f)]
    hip_messages = [m for f in hip for m in can_messages(f)]
    assert {m.arbitration_id for m in knee_messages} == {DEFAULT_BASE_ID + KNEE}
    assert all(len(m.data) <= 8 for m in knee_messages)
    interleaved = [m for pair in zip(knee_messages, hip_messages, strict=False) for m in pair]
    interleaved += knee_messages[len(hip_messages) :] + hip_messages[len(knee_messages) :]
    with CanTransport("virtual", channel) as pc, can.Bus(interface="virtual", channel=channel) as raw:
        raw.send(can.Message(arbitration_id=0x123, data=b"\x7e\x01\x02", is_extended_id=False))  # not NDLCom
        raw.send(can.Message(arbitration_id=DEFAULT_BASE_ID + KNEE, data=b"\x7e\x01", is_extended_id=True))
        for message in interleaved:
            raw.send(message)
        received = _collect(pc, 8)
    assert [f for f in received if f.sender == KNEE] == [Frame(PC, KNEE, i, bytes([i]) * 40) for i in range(4)]
    assert [f for f in received if f.sender == HIP] == [Frame(PC, HIP, i, bytes([0x7E, i]) * 20) for i in range(4)]
    stats = pc.stats()
    assert stats.foreign_chunks == 2
    assert stats.decoder.total().crc_errors == 0


def test_can_arbitration_id_reads_the_sender_through_escaping() -> None:
    for sender in (0x00, 0x7D, 0x7E, 0xFF):
        for receiver in (0x01, 0x7D, 0x7E):
            frame = encode_frame(receiver, sender, 0, b"")
            assert frame_sender(frame) == sender
            assert {m.arbitration_id for m in can_messages(frame, 0x200)} == {0x200 + sender}


def test_can_timeout_and_errors(channel: str) -> None:
    with CanTransport("virtual", channel) as pc:
        start = time.monotonic()
        assert pc.recv(0.05) == []
        assert time.monotonic() - start >= 0.04
        with pytest.raises(TransportTimeoutError):
            pc.recv_frames(1, 0.02)
        with pytest.raises(TransportOperationError, match="cannot send over CAN"):
            pc.send_frame(b"not a frame")
    pc.shutdown()
    with pytest.raises(ValueError, match="base_id"):
        CanTransport("virtual", channel, base_id=0x701)
    with pytest.raises(TransportInitError, match="cannot open CAN interface 'no-such-interface'"):
        CanTransport("no-such-interface", "can0")


# --------------------------------------------------------------------------------------------------- factory


def test_open_transport_by_name(channel: str) -> None:
    assert set(TRANSPORTS) == {"udp", "can"}
    assert transport_class("udp") is UdpTransport
    with open_transport("udp", local=LOCAL) as udp:
        assert isinstance(udp, UdpTransport)
    with open_transport("can", interface="virtual", channel=channel) as bus:
        assert isinstance(bus, CanTransport)
    with pytest.raises(ValueError, match=r"unknown transport 'serial' \(known: can, udp"):
        open_transport("serial")


def test_importing_the_factory_does_not_import_python_can() -> None:
    code = "import sys, rh5_bringup.hardware.transports; assert 'can' not in sys.modules; print('lazy')"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False)
    assert result.stdout.strip() == "lazy", result.stderr


def test_recv_newest_decodes_only_the_newest_burst_and_counts_no_loss() -> None:
    """A receiver behind its peer: of five waiting one-datagram bursts only the last is decoded; the skipped
    four are counted as superseded, and their frame-counter gap is not reported as lost frames."""
    receiver = UdpTransport(("127.0.0.1", 0))
    sender = UdpTransport(("127.0.0.1", 0), remote=receiver.local_address)
    encoder = FrameEncoder(0x01)
    try:
        for burst in range(5):
            sender.send_frames([encoder.encode(board, bytes([burst, board])) for board in (0x10, 0x11, 0x12)])
        time.sleep(0.05)
        frames = receiver.recv_newest(timeout=1.0)
        assert [f.payload for f in frames] == [bytes([4, board]) for board in (0x10, 0x11, 0x12)]
        stats = receiver.stats()
        assert stats.superseded_chunks == 4
        assert stats.decoder.total().lost == 0
        sender.send_frames([encoder.encode(0x10, b"\x05")])  # the next frame continues the counter: no loss
        assert [f.payload for f in receiver.recv_newest(timeout=1.0)] == [b"\x05"]
        assert receiver.stats().decoder.total().lost == 0
    finally:
        sender.shutdown()
        receiver.shutdown()


def test_recv_newest_keeps_a_burst_split_over_datagrams() -> None:
    """A burst that did not fit one datagram (different first frames) is kept whole; the older burst goes."""
    receiver = UdpTransport(("127.0.0.1", 0))
    sender = UdpTransport(("127.0.0.1", 0), remote=receiver.local_address)
    encoder = FrameEncoder(0x01)
    try:
        for burst in range(2):
            for half in ((0x10, 0x11), (0x12, 0x13)):  # two datagrams per burst
                sender.send_frames([encoder.encode(board, bytes([burst])) for board in half])
        time.sleep(0.05)
        frames = receiver.recv_newest(timeout=1.0)
        assert [(f.receiver, f.payload) for f in frames] == [(b, b"\x01") for b in (0x10, 0x11, 0x12, 0x13)]
        assert receiver.stats().superseded_chunks == 2
    finally:
        sender.shutdown()
        receiver.shutdown()
