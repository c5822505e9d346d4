"""The rig's serial protocol (version 1): frames, messages and a streaming parser.

Frame layout (all integers little-endian; see hw/PROTOCOL.md)::

    offset  size  field
    0       2     start marker 0xA5 0x5A
    2       1     protocol version (PROTOCOL_VERSION)
    3       1     message type (MsgType)
    4       2     sequence number (uint16, one counter per direction, wraps)
    6       2     payload length N (uint16, <= MAX_PAYLOAD, fixed per type)
    8       N     payload
    8+N     2     CRC-16/CCITT-FALSE over bytes 2 .. 8+N-1 (version to end of payload)

:class:`FrameParser` turns any byte stream into the frames it contains: it
resynchronises after garbage and only ever returns frames whose CRC, version,
type and length are all valid.
"""

from __future__ import annotations

import struct
from dataclasses import astuple, dataclass, field
from enum import IntEnum, IntFlag
from typing import ClassVar

from drillgym.errors import DrillgymError

from .crc import crc16

__all__ = [
    "PROTOCOL_VERSION",
    "START",
    "HEADER_SIZE",
    "MAX_PAYLOAD",
    "MsgType",
    "StopReason",
    "Status",
    "ProtocolError",
    "Frame",
    "Message",
    "Identify",
    "SetVoltage",
    "Heartbeat",
    "EmergencyStop",
    "ClearStop",
    "Config",
    "Sample",
    "Ack",
    "encode",
    "decode",
    "FrameParser",
    "ParserStats",
]

PROTOCOL_VERSION = 1
START = b"\xa5\x5a"
_HEADER = struct.Struct("<2sBBHH")
HEADER_SIZE = _HEADER.size  # 8 bytes
CRC_SIZE = 2
MAX_PAYLOAD = 64


class ProtocolError(DrillgymError, ValueError):
    """A frame or message that is not valid protocol (bad payload, unknown type, wrong version)."""


class MsgType(IntEnum):
    """Message types; 0x0_ are sent by the host, 0x8_ by the firmware."""

    IDENTIFY = 0x01  # host -> fw: request CONFIG, optionally set the control period
    SET_VOLTAGE = 0x02  # host -> fw: motor voltage; the firmware answers with a SAMPLE
    HEARTBEAT = 0x03  # both ways: the firmware echoes the token
    EMERGENCY_STOP = 0x04  # both ways: host request, or the firmware reporting a trip
    CLEAR_STOP = 0x05  # host -> fw: clear a latched stop (the firmware answers with ACK)
    CONFIG = 0x81  # fw -> host: identification and configuration
    SAMPLE = 0x82  # fw -> host: one sample at the end of a control period
    ACK = 0x85  # fw -> host: a command without data reply was executed


class StopReason(IntEnum):
    """Why the motor was stopped (EMERGENCY_STOP payload)."""

    HOST = 1  # the host asked for it
    OVERSPEED = 2  # |omega| above the limit
    OVER_DISPLACEMENT = 3  # LVDT displacement above the limit
    WATCHDOG = 4  # no SET_VOLTAGE for the watchdog time
    LINK_LOST = 5  # the serial link went down (USB detach, cable pulled)


class Status(IntFlag):
    """Status bits of a SAMPLE."""

    OK = 0
    STOPPED = 1  # a stop is latched: the motor is held at 0 V
    WATCHDOG = 2  # the latched stop came from the watchdog
    LIMITED = 4  # the commanded voltage was clamped or slew-limited
    SEQ_GAP = 8  # the firmware saw a gap in the host's sequence numbers (lost frame)


@dataclass(frozen=True)
class Frame:
    """A valid frame as the parser returns it.

    Parameters
    ----------
    type : int
        Message type (:class:`MsgType`).
    seq : int
        Sequence number (0 to 65535).
    payload : bytes
        The message's payload.
    version : int, optional
        Protocol version of the frame.
    """

    type: int
    seq: int
    payload: bytes
    version: int = PROTOCOL_VERSION


class Message:
    """Base of the typed messages: ``FORMAT`` is the struct layout of the payload."""

    TYPE: ClassVar[MsgType]
    FORMAT: ClassVar[struct.Struct]

    def pack(self) -> bytes:
        """The payload bytes of the message (little-endian, ``FORMAT``)."""
        return self.FORMAT.pack(*astuple(self))

    @classmethod
    def unpack(cls, payload: bytes) -> Message:
        """The message of a payload; ProtocolError when its size is not ``FORMAT.size``."""
        if len(payload) != cls.FORMAT.size:
            raise ProtocolError(f"{cls.TYPE.name} payload has {len(payload)} bytes, expected {cls.FORMAT.size}")
        return cls(*cls.FORMAT.unpack(payload))


@dataclass(frozen=True)
class Identify(Message):
    """Ask for the CONFIG, optionally setting the control period.

    Parameters
    ----------
    period_us : int, optional
        Control period to set (µs, a multiple of the plant step); 0 keeps the firmware's.
    """

    TYPE: ClassVar = MsgType.IDENTIFY
    FORMAT: ClassVar = struct.Struct("<I")
    period_us: int = 0


@dataclass(frozen=True)
class SetVoltage(Message):
    """Motor voltage to hold over the next control period.

    Parameters
    ----------
    volts : float, optional
        Voltage (V); the firmware clamps and slew-limits it.
    """

    TYPE: ClassVar = MsgType.SET_VOLTAGE
    FORMAT: ClassVar = struct.Struct("<d")
    volts: float = 0.0


@dataclass(frozen=True)
class Heartbeat(Message):
    """Link check; the firmware sends the same token back.

    Parameters
    ----------
    token : int, optional
        Unsigned 32-bit value.
    """

    TYPE: ClassVar = MsgType.HEARTBEAT
    FORMAT: ClassVar = struct.Struct("<I")
    token: int = 0


@dataclass(frozen=True)
class EmergencyStop(Message):
    """Stop the motor (0 V) and latch until CLEAR_STOP.

    Parameters
    ----------
    reason : int, optional
        A :class:`StopReason`; default ``HOST``.
    """

    TYPE: ClassVar = MsgType.EMERGENCY_STOP
    FORMAT: ClassVar = struct.Struct("<B")
    reason: int = StopReason.HOST


@dataclass(frozen=True)
class ClearStop(Message):
    """Clear a latched stop."""

    TYPE: ClassVar = MsgType.CLEAR_STOP
    FORMAT: ClassVar = struct.Struct("<")


@dataclass(frozen=True)
class Config(Message):
    """Identification and configuration of the firmware.

    Parameters
    ----------
    protocol_version : int, optional
        Protocol version the firmware speaks.
    counts_per_rev : int, optional
        Encoder counts per revolution (both discs).
    lvdt_m_per_lsb : float, optional
        LVDT scale (m per count of the raw value).
    period_us : int, optional
        Control period (µs).
    watchdog_ms : int, optional
        The motor goes to 0 V after this long without SET_VOLTAGE (ms).
    v_max : float, optional
        Amplifier range (V).
    slew_v_per_s : float, optional
        Largest voltage rate (V/s).
    max_speed : float, optional
        Over-speed threshold (rad/s).
    max_displacement : float, optional
        Lateral over-displacement threshold (m).
    firmware_id : bytes, optional
        Identifier (ASCII, 16 bytes, zero-padded).
    """

    TYPE: ClassVar = MsgType.CONFIG
    FORMAT: ClassVar = struct.Struct("<BIdIHffff16s")
    protocol_version: int = PROTOCOL_VERSION
    counts_per_rev: int = 8000
    lvdt_m_per_lsb: float = 1e-7
    period_us: int = 10000
    watchdog_ms: int = 100
    v_max: float = 5.0
    slew_v_per_s: float = 1000.0
    max_speed: float = 40.0
    max_displacement: float = 0.02
    firmware_id: bytes = b"drillgym-emu"

    @property
    def name(self) -> str:
        """The firmware identifier as text."""
        return self.firmware_id.rstrip(b"\0").decode("ascii", "replace")

    @property
    def period_s(self) -> float:
        """Control period (s)."""
        return self.period_us * 1e-6


@dataclass(frozen=True)
class Sample(Message):
    """Measurements at the end of the control period started by a SET_VOLTAGE.

    Parameters
    ----------
    ack_seq : int, optional
        Sequence number of the SET_VOLTAGE that started the period.
    timestamp_us : int, optional
        Firmware time (µs).
    counts_u, counts_l : int, optional
        Encoder counts of the upper and lower disc.
    lvdt_x, lvdt_y : int, optional
        Raw LVDT values (LSB).
    volts : float, optional
        Voltage applied over the period (V, after the firmware's safety).
    status : int, optional
        :class:`Status` bits.
    """

    TYPE: ClassVar = MsgType.SAMPLE
    FORMAT: ClassVar = struct.Struct("<HQiiiidB")
    ack_seq: int = 0
    timestamp_us: int = 0
    counts_u: int = 0
    counts_l: int = 0
    lvdt_x: int = 0
    lvdt_y: int = 0
    volts: float = 0.0
    status: int = 0


@dataclass(frozen=True)
class Ack(Message):
    """A command without data reply was executed.

    Parameters
    ----------
    acked_type : int, optional
        Its message type.
    acked_seq : int, optional
        Its sequence number.
    """

    TYPE: ClassVar = MsgType.ACK
    FORMAT: ClassVar = struct.Struct("<BH")
    acked_type: int = 0
    acked_seq: int = 0


_MESSAGES: dict[int, type[Message]] = {
    c.TYPE: c for c in (Identify, SetVoltage, Heartbeat, EmergencyStop, ClearStop, Config, Sample, Ack)
}
PAYLOAD_SIZES = {t: c.FORMAT.size for t, c in _MESSAGES.items()}
assert max(PAYLOAD_SIZES.values()) <= MAX_PAYLOAD


def encode(msg: Message, seq: int) -> bytes:
    """The frame of a message: start marker, version, type, sequence, length, payload, CRC-16.

    Parameters
    ----------
    msg : Message
        The message (its ``TYPE`` and packed payload).
    seq : int
        Sequence number, taken modulo 2**16.

    Returns
    -------
    bytes
        The complete frame, little-endian (``PROTOCOL.md``).
    """
    payload = msg.pack()
    body = _HEADER.pack(START, PROTOCOL_VERSION, int(msg.TYPE), seq & 0xFFFF, len(payload)) + payload
    return body + struct.pack("<H", crc16(body[2:]))


def decode(frame: Frame) -> Message:
    """The typed message of a valid frame.

    Parameters
    ----------
    frame : Frame
        A frame returned by :meth:`FrameParser.feed` (CRC already checked).

    Returns
    -------
    Message
        The message of the frame's type, its fields unpacked.

    Raises
    ------
    ProtocolError
        An unknown message type or a payload of the wrong size.
    """
    cls = _MESSAGES.get(frame.type)
    if cls is None:
        raise ProtocolError(f"unknown message type 0x{frame.type:02x}")
    return cls.unpack(frame.payload)


@dataclass
class ParserStats:
    """What the parser threw away (counts)."""

    frames: int = 0  # valid frames returned
    garbage_bytes: int = 0  # bytes skipped while looking for a start marker
    bad_headers: int = 0  # length above MAX_PAYLOAD
    crc_errors: int = 0  # CRC mismatch: a corrupted frame, rejected
    malformed: int = 0  # CRC fine but unknown type or wrong length for its type
    foreign_versions: set = field(default_factory=set)  # protocol versions seen but not spoken

    @property
    def rejected(self) -> int:
        return self.bad_headers + self.crc_errors + self.malformed + len(self.foreign_versions)


class FrameParser:
    """Streaming frame parser: ``feed(bytes)`` returns the complete valid frames seen so far.

    After garbage or a corrupted frame it resynchronises on the next start marker (a frame is
    rejected by skipping one byte and searching again, so a valid frame hidden behind a bad one
    is still found).

    Attributes
    ----------
    stats : ParserStats
        Counts of the frames returned and of what was thrown away.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = ParserStats()

    def reset(self) -> None:
        """Drop the bytes held (the statistics are kept)."""
        self._buf.clear()

    @property
    def pending(self) -> int:
        """Bytes held waiting for the rest of a frame."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Frame]:
        """Add received bytes and return the frames they complete.

        Parameters
        ----------
        data : bytes
            Bytes read from the link, any split.

        Returns
        -------
        list of Frame
            The complete frames with a valid CRC of this protocol version, in order; the bytes of an
            incomplete frame are held for the next call.
        """
        buf = self._buf
        buf += data
        out: list[Frame] = []
        st = self.stats
        while True:
            i = buf.find(START)
            if i < 0:
                keep = 1 if buf[-1:] == START[:1] else 0
                st.garbage_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                break
            if i:
                st.garbage_bytes += i
                del buf[:i]
            if len(buf) < HEADER_SIZE:
                break
            _, version, mtype, seq, n = _HEADER.unpack_from(buf)
            if n > MAX_PAYLOAD:
                st.bad_headers += 1
                del buf[:1]
                continue
            if version == PROTOCOL_VERSION and PAYLOAD_SIZES.get(mtype) != n:
                st.malformed += 1  # unknown type or wrong length for it: no need to wait for the body
                del buf[:1]
                continue
            total = HEADER_SIZE + n + CRC_SIZE
            if len(buf) < total:
                break
            (crc,) = struct.unpack_from("<H", buf, HEADER_SIZE + n)
            if crc16(buf[2 : HEADER_SIZE + n]) != crc:
                st.crc_errors += 1
                del buf[:1]
                continue
            if version != PROTOCOL_VERSION:
                st.foreign_versions.add(version)
                del buf[:1]
                continue
            out.append(Frame(mtype, seq, bytes(buf[HEADER_SIZE : HEADER_SIZE + n]), version))
            st.frames += 1
            del buf[:total]
        return out
