"""Serial protocol: CRC, frames, messages, streaming parser (resync, rejection), fuzzing."""

from __future__ import annotations

import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hw import protocol as P
from hw.crc import CRC16_CHECK, crc16
from hw.link import SerialLink

MESSAGES = [
    P.Identify(10000),
    P.SetVoltage(-2.75),
    P.Heartbeat(0xDEADBEEF),
    P.EmergencyStop(P.StopReason.OVERSPEED),
    P.ClearStop(),
    P.Config(),
    P.Sample(7, 123456789, -5, 2**31 - 1, -12, 34, 1.25, 5),
    P.Ack(2, 65535),
]


def _crc_bitwise(data: bytes) -> int:
    """Reference CRC-16/CCITT-FALSE, bit by bit (poly 0x1021, init 0xFFFF)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def test_crc_check_value_and_reference():
    assert crc16(b"123456789") == CRC16_CHECK == 0x29B1
    for data in (b"", b"\x00", bytes(range(256)), b"drillgym" * 9):
        assert crc16(data) == _crc_bitwise(data)


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: type(m).__name__)
def test_every_message_round_trips(msg):
    frame = P.encode(msg, 513)
    assert frame[:2] == P.START and frame[2] == P.PROTOCOL_VERSION and frame[3] == msg.TYPE
    assert struct.unpack_from("<HH", frame, 4) == (513, len(frame) - P.HEADER_SIZE - 2)
    (f,) = P.FrameParser().feed(frame)
    assert (f.type, f.seq) == (msg.TYPE, 513)
    decoded = P.decode(f)
    assert P.encode(decoded, 513) == frame
    if not isinstance(msg, P.Config):  # Config's limits travel as float32
        assert decoded == msg


def test_parser_reassembles_split_frames_and_skips_garbage():
    stream = b"\x00\xa5\xa5junk" + P.encode(MESSAGES[6], 1) + b"\x5a\xa5" + P.encode(MESSAGES[1], 2)
    p = P.FrameParser()
    got = []
    for b in stream:  # one byte at a time
        got += p.feed(bytes([b]))
    assert [P.decode(f) for f in got] == [MESSAGES[6], MESSAGES[1]]
    assert p.stats.garbage_bytes == 9 and p.stats.crc_errors == 0


def test_parser_rejects_corrupted_frame_and_keeps_the_next():
    bad = bytearray(P.encode(MESSAGES[6], 1))
    bad[12] ^= 0x01
    p = P.FrameParser()
    got = p.feed(bytes(bad) + P.encode(MESSAGES[3], 2))
    assert [(f.seq, P.decode(f)) for f in got] == [(2, MESSAGES[3])]
    assert p.stats.crc_errors == 1


def test_parser_rejects_foreign_version_unknown_type_wrong_length_and_oversize():
    def frame(version, mtype, payload):
        body = struct.pack("<2sBBHH", P.START, version, mtype, 0, len(payload)) + payload
        return body + struct.pack("<H", crc16(body[2:]))

    p = P.FrameParser()
    assert p.feed(frame(2, P.MsgType.SET_VOLTAGE, bytes(8))) == []
    assert p.feed(frame(1, 0x7E, b"")) == []  # unknown type
    assert p.feed(frame(1, P.MsgType.SET_VOLTAGE, bytes(4))) == []  # wrong length for the type
    assert p.feed(struct.pack("<2sBBHH", P.START, 1, 2, 0, 999)) == []  # length above MAX_PAYLOAD
    assert p.stats.foreign_versions == {2} and p.stats.malformed == 2 and p.stats.bad_headers == 1
    assert [P.decode(f) for f in p.feed(P.encode(MESSAGES[1], 5))] == [MESSAGES[1]]
    with pytest.raises(P.ProtocolError, match="SET_VOLTAGE payload has 4 bytes"):
        P.SetVoltage.unpack(bytes(4))


def test_link_over_pyserial_loop_url():
    link = SerialLink("loop://")
    seq = link.send(P.Heartbeat(42))
    import time

    [(frame, _)] = link.receive(time.monotonic() + 0.5)
    assert frame.seq == seq and P.decode(frame) == P.Heartbeat(42)
    link.close()
    with pytest.raises(FileNotFoundError, match="does not exist"):
        SerialLink("/dev/does-not-exist-drillgym")


def test_a_stop_with_an_unknown_reason_is_a_link_fault_not_an_internal_error():
    from hw.client import RigClient
    from hw.link import LinkCorruptError

    client = RigClient("loop://")  # pyserial's loop URL reads back what is written: the stop comes "from the firmware"
    client.link.send(P.EmergencyStop(99))
    with pytest.raises(LinkCorruptError, match="unknown reason 99"):
        client.stop_reason(wait_s=0.5)
    client.close()


# ---------------------------------------------------------------- fuzzing (>= 10,000 frames in all)
TYPES = sorted(P.PAYLOAD_SIZES)
FUZZ = settings(
    max_examples=2500,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
IDLE = bytes(P.HEADER_SIZE + P.MAX_PAYLOAD + 2)  # line traffic after the test stream


@st.composite
def frame_specs(draw):
    """A valid frame (random type, sequence number and payload) and a mutation of it."""
    mtype = draw(st.sampled_from(TYPES))
    n = P.PAYLOAD_SIZES[mtype]
    raw = draw(st.binary(min_size=n + 2, max_size=n + 2))  # sequence number and payload
    body = struct.pack("<2sBBHH", P.START, P.PROTOCOL_VERSION, mtype, int.from_bytes(raw[:2], "little"), n) + raw[2:]
    frame = body + struct.pack("<H", crc16(body[2:]))
    kind = draw(st.sampled_from(["none", "burst", "bits", "truncate", "garbage"]))
    out = bytearray(frame)
    nbits = 8 * len(out)
    if kind == "burst":  # an error burst of up to 16 bits: CRC-16 detects every one
        v = draw(st.integers(0, (nbits - 16) * 0x10000 - 1))
        start, pattern = divmod(v, 0x10000)
        flips = [start + i for i in range(16) if (pattern | 1) >> i & 1]
    elif kind == "bits":  # 1 to 3 flipped bits anywhere (CRC-16/CCITT-FALSE: Hamming distance 4)
        flips = set(draw(st.lists(st.integers(0, nbits - 1), min_size=1, max_size=3)))
    else:
        flips = []
    for bit in flips:
        out[bit // 8] ^= 0x80 >> (bit % 8)
    if kind == "truncate":
        out = out[: draw(st.integers(0, len(out) - 1))]
    if kind == "garbage":  # bytes before the frame
        out = bytearray(draw(st.binary(max_size=24))) + out
    return frame, bytes(out), kind


@FUZZ
@given(st.binary(max_size=400))
def test_fuzz_random_bytes_never_crash(data):
    p = P.FrameParser()
    frames = p.feed(data) + p.feed(data[::-1]) + p.feed(IDLE)
    for f in frames:  # anything accepted is a complete, valid frame
        assert f.version == P.PROTOCOL_VERSION
        P.decode(f)
    assert p.pending <= P.HEADER_SIZE + P.MAX_PAYLOAD + 2


@FUZZ
@given(st.lists(frame_specs(), min_size=1, max_size=8), st.integers(1, 64))
def test_fuzz_mutated_frames_never_accepted(specs, chunk):
    """Streams of valid and mutated frames, fed in chunks: no damaged frame is ever accepted and,
    unless a truncated frame leaves a prefix, every intact frame comes out, in order."""
    stream = b"".join(out for _, out, _ in specs) + IDLE
    p = P.FrameParser()
    got = []
    for i in range(0, len(stream), chunk):
        got += p.feed(stream[i : i + chunk])
    got_bytes = [stream_bytes(f) for f in got]
    originals = [frame for frame, _, _ in specs]
    for g in got_bytes:  # accepted frames are original frames, nothing else
        assert g in originals
    if all(kind != "truncate" for _, _, kind in specs):
        assert got_bytes == [frame for frame, _, kind in specs if kind in ("none", "garbage")]


def stream_bytes(f: P.Frame) -> bytes:
    body = struct.pack("<2sBBHH", P.START, f.version, f.type, f.seq, len(f.payload)) + f.payload
    return body + struct.pack("<H", crc16(body[2:]))
