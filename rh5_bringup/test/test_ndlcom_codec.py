"""NDLCom framing: the ARCHITECTURE test vector, round trips, chunking, a 100k-stream fuzz and exact error counts."""

from __future__ import annotations

import random
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rh5_bringup.hardware.ndlcom.codec import (
    FCS_TABLE,
    MAX_ENCODED_SIZE,
    DecoderStats,
    Frame,
    FrameCounter,
    FrameDecoder,
    FrameEncoder,
    FrameError,
    LinkCounters,
    SenderStats,
    encode_frame,
    fcs16,
    fcs16_reference,
)

VECTOR_FRAME = bytes.fromhex("7e 01 02 03 04 7d 5e 7d 5d 00 ff 3d 6f 7e")
"""design/ARCHITECTURE.md "The wire to the boards": receiver 1, sender 2, counter 3, payload 7E 7D 00 FF."""

byte = st.integers(0, 255)
payloads = st.binary(min_size=0, max_size=255)


def raw_frame(receiver: int, sender: int, counter: int, payload: bytes, *, length: int | None = None) -> bytes:
    """A frame built independently of encode_frame (the reference FCS, byte-wise escaping), optionally lying
    about its length field."""
    body = bytes([receiver, sender, counter, len(payload) if length is None else length]) + payload
    body += struct.pack("<H", fcs16_reference(body))
    escaped = bytearray()
    for b in body:
        escaped += bytes([0x7D, b ^ 0x20]) if b in (0x7D, 0x7E) else bytes([b])
    return b"\x7e" + bytes(escaped) + b"\x7e"


def flip_bit(frame: bytes, index: int, bit: int) -> bytes:
    out = bytearray(frame)
    out[index] ^= 1 << bit
    return bytes(out)


# --------------------------------------------------------------------------------------------------- the vector


def test_architecture_test_vector_encodes() -> None:
    assert encode_frame(0x01, 0x02, 0x03, bytes([0x7E, 0x7D, 0x00, 0xFF])) == VECTOR_FRAME


def test_architecture_test_vector_decodes() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(VECTOR_FRAME) == [Frame(1, 2, 3, b"\x7e\x7d\x00\xff")]
    assert decoder.stats() == DecoderStats(0, {2: SenderStats(1, 0, 0, 0, 0)})


def test_fcs_table_is_the_rfc_1662_table() -> None:
    assert len(FCS_TABLE) == 256
    assert FCS_TABLE[:4] == (0x0000, 0x1189, 0x2312, 0x329B)
    assert FCS_TABLE[255] == 0x0F78
    assert fcs16_reference(bytes([1, 2, 3, 4, 0x7E, 0x7D, 0x00, 0xFF])) == 0x6F3D


@given(st.binary(max_size=300))
def test_fast_fcs_equals_the_table_loop_and_leaves_zero_residue(data: bytes) -> None:
    fcs = fcs16(data)
    assert fcs == fcs16_reference(data)
    assert fcs16_reference(data + struct.pack("<H", fcs)) == 0x0000


# --------------------------------------------------------------------------------------------------- round trips


@given(byte, byte, byte, payloads)
def test_any_frame_round_trips(receiver: int, sender: int, counter: int, payload: bytes) -> None:
    encoded = encode_frame(receiver, sender, counter, payload)
    assert encoded == raw_frame(receiver, sender, counter, payload)
    assert encoded[0] == encoded[-1] == 0x7E
    assert 0x7E not in encoded[1:-1]
    assert len(encoded) <= MAX_ENCODED_SIZE
    assert FrameDecoder().feed(encoded) == [(receiver, sender, counter, payload)]


@settings(max_examples=200)
@given(
    st.lists(st.tuples(byte, byte, byte, payloads), min_size=1, max_size=6),
    st.lists(st.integers(0, 2000), max_size=12),
    st.data(),
)
def test_frames_round_trip_through_any_chunking(
    frames: list[tuple[int, int, int, bytes]], cuts: list[int], data: st.DataObject
) -> None:
    stream = b"".join(encode_frame(*f) for f in frames)
    if data.draw(st.booleans()):
        stream = b"".join(f[1:] if i else f for i, f in enumerate(encode_frame(*f) for f in frames))  # shared flags
    positions = sorted({min(c, len(stream)) for c in cuts})
    chunks = [stream[a:b] for a, b in zip([0, *positions], [*positions, len(stream)], strict=True)]
    decoder = FrameDecoder()
    received = [frame for chunk in chunks for frame in decoder.feed(memoryview(chunk))]
    assert received == [Frame(*f) for f in frames]
    total = decoder.stats().total()
    assert (total.frames, total.crc_errors, total.malformed, total.oversize) == (len(frames), 0, 0, 0)
    assert decoder.stats().garbage_bytes == 0


def test_byte_by_byte_feeding_and_input_types() -> None:
    decoder = FrameDecoder()
    frames = []
    for i, b in enumerate(VECTOR_FRAME * 3):
        kind = (bytes, bytearray, memoryview)[i % 3]
        frames += decoder.feed(kind(bytes([b])))
    assert frames == [Frame(1, 2, 3, b"\x7e\x7d\x00\xff")] * 3
    assert decoder.feed(b"") == []


def test_decoder_joining_mid_frame_drops_the_tail_as_garbage() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(VECTOR_FRAME[5:] + VECTOR_FRAME) == [Frame(1, 2, 3, b"\x7e\x7d\x00\xff")]
    assert decoder.stats().garbage_bytes == len(VECTOR_FRAME) - 5 - 1  # up to the first flag, which it consumes


def test_encoder_rejects_fields_outside_a_byte() -> None:
    with pytest.raises(FrameError, match=r"payloads 0\.\.255 bytes"):
        encode_frame(1, 2, 3, bytes(256))
    for header in ((256, 2, 3), (1, -1, 3), (1, 2, 300)):
        with pytest.raises(FrameError, match=r"header fields are 0\.\.255"):
            encode_frame(*header, b"")


def test_frame_counter_keeps_one_wrapping_counter_per_receiver() -> None:
    counter = FrameCounter()
    assert [counter.next(7) for _ in range(258)] == [*range(256), 0, 1]
    assert counter.next(8) == 0
    assert counter.peek(7) == 2
    encoder = FrameEncoder(0x01)
    frames = FrameDecoder().feed(b"".join(encoder.encode(r, b"x") for r in (0x10, 0x10, 0x11, 0x10)))
    assert [(f.receiver, f.counter) for f in frames] == [(0x10, 0), (0x10, 1), (0x11, 0), (0x10, 2)]
    with pytest.raises(FrameError):
        FrameEncoder(256)


# --------------------------------------------------------------------------------------------------- exact counts


def test_crc_errors_are_counted_per_sender() -> None:
    good = encode_frame(1, 0x20, 0, b"\x01\x02\x03\x04")
    decoder = FrameDecoder()
    assert decoder.feed(flip_bit(good, 6, 0)) == []  # payload byte 0x01 -> 0x00
    assert decoder.feed(flip_bit(good, len(good) - 2, 3)) == []  # FCS high byte
    assert decoder.feed(good) == [Frame(1, 0x20, 0, b"\x01\x02\x03\x04")]
    assert decoder.stats().senders == {0x20: SenderStats(frames=1, crc_errors=2, malformed=0, oversize=0, lost=0)}


def test_length_field_disagreeing_with_a_good_fcs_is_malformed() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(raw_frame(1, 0x21, 0, b"abc", length=4)) == []
    assert decoder.feed(raw_frame(1, 0x21, 1, b"abc", length=2)) == []
    assert decoder.stats().senders[0x21] == SenderStats(0, 0, 2, 0, 0)


def test_invalid_and_dangling_escapes_are_malformed() -> None:
    decoder = FrameDecoder()
    good = encode_frame(1, 0x22, 0, b"abcd")
    invalid = good[:6] + b"\x7d\x41" + good[6:]  # 0x7D must be followed by 0x5E or 0x5D
    dangling = good[:-1] + b"\x7d\x7e"  # escape directly before the flag (RFC 1662 abort)
    assert decoder.feed(invalid + dangling + good) == [Frame(1, 0x22, 0, b"abcd")]
    assert decoder.stats().senders[0x22] == SenderStats(1, 0, 2, 0, 0)


def test_oversize_frames_are_counted_and_resynchronised() -> None:
    decoder = FrameDecoder()
    too_long = raw_frame(1, 0x23, 0, bytes(300), length=0xFF)  # 306 bytes between the flags, > 4 + 255 + 2
    assert decoder.feed(too_long) == []
    run = b"\x7e\x01\x23" + b"\x55" * 600  # never closed: dropped once it exceeds 522 escaped bytes
    assert decoder.feed(run) == []
    assert decoder.feed(b"\x55" * 10 + VECTOR_FRAME) == [Frame(1, 2, 3, b"\x7e\x7d\x00\xff")]
    stats = decoder.stats()
    assert stats.senders[0x23] == SenderStats(0, 0, 0, 2, 0)
    assert stats.garbage_bytes == 10  # the bytes after the dropped run, up to the next flag


def test_largest_frame_is_not_oversize() -> None:
    payload = bytes([0x7E]) * 255  # every payload byte escaped
    frame = encode_frame(0x7D, 0x7E, 0x7D, payload)
    assert len(frame) == 2 + 3 * 2 + 1 + 255 * 2 + 2  # flags, escaped header but 0xFF, escaped payload, FCS
    decoder = FrameDecoder()
    assert decoder.feed(frame[:300]) == []
    assert decoder.feed(frame[300:]) == [Frame(0x7D, 0x7E, 0x7D, payload)]


def test_lost_frames_are_counter_gaps_per_sender_and_receiver_modulo_256() -> None:
    decoder = FrameDecoder()
    stream = [encode_frame(1, 0x30, c, b"") for c in (0, 1, 2, 5, 6)]  # 3 and 4 lost
    stream += [encode_frame(1, 0x31, c, b"") for c in (254, 255, 0, 1)]  # wraps, nothing lost
    stream += [encode_frame(1, 0x32, c, b"") for c in (250, 3)]  # 251..255, 0..2 lost
    # one sender, two receivers: independent counters interleaved, nothing lost
    stream += [encode_frame(r, 0x33, c, b"") for r, c in ((1, 0), (2, 7), (1, 1), (2, 8), (0xFF, 0), (1, 2))]
    decoder.feed(b"".join(stream))
    senders = decoder.stats().senders
    assert senders[0x30].lost == 2
    assert senders[0x31].lost == 0
    assert senders[0x32].lost == 8
    assert senders[0x33] == SenderStats(6, 0, 0, 0, 0)


def test_garbage_bytes_and_short_candidates() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(b"abc" + VECTOR_FRAME + b"\x01\x02\x7e" + VECTOR_FRAME) == [Frame(1, 2, 3, b"~}\x00\xff")] * 2
    assert decoder.stats().garbage_bytes == 3 + 2


def test_shared_counters_aggregate_several_decoders() -> None:
    counters = LinkCounters()
    a, b = FrameDecoder(counters), FrameDecoder(counters)
    a.feed(encode_frame(1, 5, 0, b"x"))
    b.feed(encode_frame(1, 6, 0, b"y"))
    assert a.stats() == b.stats() == DecoderStats(0, {5: SenderStats(1, 0, 0, 0, 0), 6: SenderStats(1, 0, 0, 0, 0)})
    assert a.stats().total() == SenderStats(2, 0, 0, 0, 0)
    a.reset()
    assert a.feed(VECTOR_FRAME[3:]) == []


# --------------------------------------------------------------------------------------------------- fuzz

FUZZ_STREAMS = 100_000


def test_fuzz_decoder_never_raises_and_recovers_the_next_good_frame() -> None:
    """100,000 damaged streams (garbage, bit flips, truncations, inserted flags and escapes, long runs), each
    followed by a good frame, through one long-lived decoder fed in two random chunks."""
    rng = random.Random(20260521)
    noise = np.random.default_rng(20260521).integers(0, 256, size=4_000_000, dtype=np.uint8).tobytes()
    # ~40-byte telemetry-like frames, from random headers and payloads
    templates = [
        encode_frame(rng.randrange(256), rng.randrange(256), rng.randrange(256), noise[i * 64 : i * 64 + (i % 80)])
        for i in range(512)
    ]
    decoder = FrameDecoder()
    offset = 0
    kinds = [0] * 8
    long_runs = 0  # runs longer than any escaped frame (522 bytes): certainly oversize
    for i in range(FUZZ_STREAMS):
        kind = i % 8
        kinds[kind] += 1
        template = templates[i % 512]
        if kind == 0:  # random garbage
            size = rng.randrange(64)
            damaged = noise[offset : offset + size]
            offset = (offset + size) % 3_900_000
        elif kind == 1:  # 1..3 bit flips in a good frame
            damaged = template
            for _ in range(rng.randrange(1, 4)):
                damaged = flip_bit(damaged, rng.randrange(len(damaged)), rng.randrange(8))
        elif kind == 2:  # truncated frame
            damaged = template[: rng.randrange(len(template))]
        elif kind == 3:  # flag inserted inside a frame
            cut = rng.randrange(1, len(template))
            damaged = template[:cut] + b"\x7e" + template[cut:]
        elif kind == 4:  # escape inserted (possibly dangling before a flag)
            cut = rng.randrange(1, len(template))
            damaged = template[:cut] + b"\x7d" + template[cut:]
        elif kind == 5:  # bytes dropped from the middle
            a = rng.randrange(1, len(template))
            damaged = template[:a] + template[a + rng.randrange(1, 4) :]
        elif kind == 6:  # long run with no flag (oversize), sometimes opened by a flag
            size = rng.randrange(500, 700)
            long_runs += size > MAX_ENCODED_SIZE - 2
            damaged = rng.choice((b"", b"\x7e")) + noise[offset : offset + size].replace(b"\x7e", b"\x00")
            offset = (offset + size) % 3_900_000
        else:  # garbage with a good frame's prefix spliced in
            damaged = noise[offset : offset + 8] + template[: rng.randrange(len(template))] + noise[offset : offset + 5]
            offset = (offset + 13) % 3_900_000
        sentinel = Frame(0x01, 0x10 + i % 32, i % 256, struct.pack("<I", i))
        stream = damaged + encode_frame(*sentinel)
        cut = rng.randrange(len(stream) + 1)
        frames = decoder.feed(stream[:cut]) + decoder.feed(stream[cut:])
        assert frames, f"stream {i} (kind {kind}): the good frame was not recovered"
        assert frames[-1] == sentinel, f"stream {i} (kind {kind}): {frames[-1]} != {sentinel}"
    stats = decoder.stats()
    total = stats.total()
    assert total.frames >= FUZZ_STREAMS
    assert total.crc_errors > 0
    assert total.malformed > 0
    assert total.oversize >= long_runs > 0
    assert min(kinds) == FUZZ_STREAMS // 8
    assert stats.garbage_bytes > 0


# --------------------------------------------------------------------------------------------------- C vs the spec


def spec_decode(stream: bytes) -> tuple[list[Frame], LinkCounters]:
    """docs/protocol.md's decoding rules written out byte by byte, slowly: the oracle for the C deframer.

    Bytes before the first flag are garbage; every flag ends a candidate; an unfinished tail is not decoded,
    but one longer than any escaped frame is counted oversize.
    """
    counters, frames = LinkCounters(), []
    first = stream.find(b"\x7e")
    if first < 0:
        counters.garbage_bytes += len(stream)
        return frames, counters
    counters.garbage_bytes += first
    *candidates, tail = stream[first + 1 :].split(b"\x7e")
    if len(tail) > MAX_ENCODED_SIZE - 2:
        counters.oversize[spec_decode_sender(tail[:8])] += 1
    for escaped in candidates:
        if len(escaped) < 6:
            counters.garbage_bytes += len(escaped)
            continue
        body, i, valid = bytearray(), 0, True
        while i < len(escaped):
            b = escaped[i]
            if b == 0x7D:
                if i + 1 == len(escaped) or escaped[i + 1] not in (0x5E, 0x5D):
                    valid = False
                    b = 0x7D
                else:
                    i += 1
                    b = escaped[i] ^ 0x20
            body.append(b)
            i += 1
        attributed = body[1] if len(body) > 1 else 0  # the sender byte as far as it can be read
        if len(escaped) > MAX_ENCODED_SIZE - 2:
            head = spec_decode_sender(escaped[:8])
            counters.oversize[head] += 1
        elif not valid:
            counters.malformed[attributed] += 1
        elif len(body) < 6:
            counters.garbage_bytes += len(escaped)
        elif len(body) > 261:
            counters.oversize[body[1]] += 1
        elif fcs16_reference(bytes(body)) != 0:
            counters.crc_errors[body[1]] += 1
        elif body[3] != len(body) - 6:
            counters.malformed[body[1]] += 1
        else:
            receiver, sender, counter = body[0], body[1], body[2]
            previous = counters.last_counter[sender << 8 | receiver]
            if previous >= 0:
                counters.lost[sender] += (counter - previous - 1) & 0xFF
            counters.last_counter[sender << 8 | receiver] = counter
            counters.frames[sender] += 1
            frames.append(Frame(receiver, sender, counter, bytes(body[4:-2])))
    return frames, counters


def spec_decode_sender(escaped: bytes) -> int:
    """The second byte of ``escaped`` read through well-formed escapes (attribution of an oversize run)."""
    raw, i = bytearray(), 0
    while i < len(escaped):
        if escaped[i] == 0x7D and i + 1 < len(escaped) and escaped[i + 1] in (0x5E, 0x5D):
            raw.append(escaped[i + 1] ^ 0x20)
            i += 2
        else:
            raw.append(escaped[i])
            i += 1
    return raw[1] if len(raw) > 1 else 0


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.tuples(byte, byte, byte, payloads).map(lambda f: encode_frame(*f)),
            st.binary(max_size=40),
            st.sampled_from([b"\x7e", b"\x7d", b"\x7d\x7e", b"\x7e\x7e", b"\x7d\x5e", bytes(600)]),
            st.tuples(byte, byte, byte, payloads, st.integers(0, 40), st.integers(0, 7)).map(
                lambda f: flip_bit(encode_frame(*f[:4]), f[4] % (len(f[3]) + 8), f[5])
            ),
        ),
        max_size=12,
    ),
    st.integers(0, 10_000),
)
def test_decoder_follows_the_spec_on_any_stream(pieces: list[bytes], cut: int) -> None:
    """The C deframer (through FrameDecoder) gives the spec's frames and every count; fed in two chunks, the
    same frames (a chunk boundary inside an oversize run turns part of it into garbage instead)."""
    stream = b"".join(pieces)
    expected_frames, expected = spec_decode(stream)
    whole = FrameDecoder()
    assert whole.feed(stream) == expected_frames
    assert whole.stats() == expected.snapshot()
    assert whole.counters.last_counter == expected.last_counter
    cut %= len(stream) + 1
    chunked = FrameDecoder()
    assert chunked.feed(stream[:cut]) + chunked.feed(stream[cut:]) == expected_frames
