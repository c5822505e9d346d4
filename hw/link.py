"""Host end of the serial link: frames over pyserial, with the link errors the host raises.

:class:`SerialLink` opens any pyserial port or URL (``/dev/ttyUSB0``, a pseudo-terminal,
``socket://host:port``, ``loop://``, ``rfc2217://host:port``) with
:func:`serial.serial_for_url`, writes encoded messages with per-direction sequence
numbers and reads the valid frames (:class:`hw.protocol.FrameParser`).  Any I/O failure
becomes a :class:`LinkLostError`.
"""

from __future__ import annotations

import time

import serial

from drillgym.errors import SafetyError, UnavailableError

try:  # pyserial's POSIX flush() calls termios directly, whose error is not an OSError
    import termios

    PORT_ERRORS: tuple = (serial.SerialException, OSError, termios.error)
except ImportError:  # pragma: no cover - Windows
    PORT_ERRORS = (serial.SerialException, OSError)


from . import protocol as P
from .checks import check_port, integer

__all__ = [
    "LinkError",
    "LinkLostError",
    "LinkTimeoutError",
    "LinkCorruptError",
    "LinkSequenceError",
    "SerialLink",
    "DEFAULT_BAUDRATE",
]

DEFAULT_BAUDRATE = 921600


class LinkError(SafetyError):
    """The serial link to the rig failed; the motor has been (or is being) brought to 0 V."""


class LinkLostError(LinkError):
    """The serial port disappeared or cannot be read/written (unplugged, peer gone)."""


class LinkTimeoutError(LinkError):
    """No reply in time (frame lost or late, firmware not responding)."""


class LinkCorruptError(LinkError):
    """A corrupted frame (CRC mismatch, garbage bytes) arrived from the firmware."""


class LinkSequenceError(LinkError):
    """A frame from the firmware is missing (gap in sequence numbers) or out of order."""


#: A write that the port cannot take within this time means the peer stopped reading (s).  pyserial also
#: raises it when the writing thread was merely descheduled that long after a complete write (its timer
#: is checked after os.write), which a 50 ms limit met on a loaded machine; the reply timeout (default
#: 100 ms) and the firmware's watchdog detect a silent rig long before a serial buffer fills.
WRITE_TIMEOUT_S = 0.5


class SerialLink:
    """Framed, sequenced messages over a pyserial port.

    Parameters
    ----------
    url : str
        Device path or pyserial URL.
    baudrate : int, optional
        Line speed (bit/s); ignored by pseudo-terminals and sockets.
    """

    def __init__(self, url: str, baudrate: int = DEFAULT_BAUDRATE) -> None:
        self.url = check_port(url, "serial port")
        integer(baudrate, "baudrate", low=1)
        try:
            self.ser = serial.serial_for_url(self.url, baudrate=baudrate, timeout=0.002, write_timeout=WRITE_TIMEOUT_S)
        except PORT_ERRORS as exc:
            raise UnavailableError(f"cannot open serial port {self.url!r}: {exc}") from None
        self.parser = P.FrameParser()
        self._tx_seq = 0
        self._rx_seq: int | None = None
        self.seq_gaps = 0

    # ------------------------------------------------------------------ state
    @property
    def is_open(self) -> bool:
        """True while the port is open."""
        return self.ser is not None and self.ser.is_open

    def close(self) -> None:
        """Close the port (idempotent; errors of a vanished port are ignored)."""
        if self.ser is not None:
            try:
                self.ser.close()
            except PORT_ERRORS:
                pass
            self.ser = None

    def flush_input(self) -> None:
        """Drop whatever is waiting (stale replies) and restart sequence tracking."""
        try:
            self.ser.reset_input_buffer()
        except PORT_ERRORS as exc:
            raise LinkLostError(f"serial port {self.url!r} disconnected ({exc})") from None
        self.parser.reset()
        self._rx_seq = None

    # ------------------------------------------------------------------ I/O
    def send(self, msg: P.Message) -> int:
        """Write one message.

        Parameters
        ----------
        msg : hw.protocol.Message
            The message.

        Returns
        -------
        int
            Its sequence number.

        Raises
        ------
        LinkLostError
            The port is closed, disconnected or does not accept data.
        """
        if not self.is_open:
            raise LinkLostError(f"serial port {self.url!r} is closed")
        seq = self._tx_seq
        self._tx_seq = (seq + 1) & 0xFFFF
        try:
            self.ser.write(P.encode(msg, seq))
            self.ser.flush()
        except serial.SerialTimeoutException:
            raise LinkLostError(
                f"serial port {self.url!r} not accepting data: write timed out (disconnected, or peer not reading)"
            ) from None
        except PORT_ERRORS as exc:
            raise LinkLostError(f"serial port {self.url!r} disconnected (write failed: {exc})") from None
        return seq

    def receive(self, deadline: float) -> list[tuple[P.Frame, float]]:
        """Read valid frames until at least one arrived or the deadline passed.

        Tracks the firmware's sequence numbers.

        Parameters
        ----------
        deadline : float
            Latest time to wait until (s, ``time.monotonic``).

        Returns
        -------
        list of tuple
            ``(frame, arrival time)`` pairs (arrival in s, ``time.monotonic``); empty at the deadline.

        Raises
        ------
        LinkLostError
            The port is closed or disconnected.
        """
        if not self.is_open:
            raise LinkLostError(f"serial port {self.url!r} is closed")
        out: list[tuple[P.Frame, float]] = []
        while True:
            try:
                data = self.ser.read(1)
                if data:
                    data += self.ser.read(self.ser.in_waiting)
            except PORT_ERRORS as exc:
                raise LinkLostError(f"serial port {self.url!r} disconnected (read failed: {exc})") from None
            now = time.monotonic()
            for f in self.parser.feed(data) if data else ():
                if self._rx_seq is not None and f.seq != self._rx_seq:
                    self.seq_gaps += 1
                self._rx_seq = (f.seq + 1) & 0xFFFF
                out.append((f, now))
            if out or now >= deadline:
                return out
