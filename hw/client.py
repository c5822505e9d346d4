"""The host's protocol client: identify the firmware, exchange voltage for samples, stop.

Every failure is detected and named: a corrupted frame (CRC), a missing frame (sequence
gap), no reply in time (lost/late frame, firmware dead), a lost port, a foreign protocol
version.  The client never retries a SET_VOLTAGE: on the rig a repeated command would
move the plant twice.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from . import protocol as P
from .checks import number
from .link import DEFAULT_BAUDRATE, LinkCorruptError, LinkError, LinkSequenceError, LinkTimeoutError, SerialLink

__all__ = ["RigClient", "Reply"]


@dataclass(frozen=True)
class Reply:
    """A SAMPLE with host-side timing: ``sent``/``received`` (time.monotonic, s), and the stop the
    firmware reported since the previous reply (StopReason or None)."""

    sample: P.Sample
    sent: float
    received: float
    stop: P.StopReason | None = None

    @property
    def round_trip(self) -> float:
        return self.received - self.sent


HANDSHAKE_TIMEOUT_S = 1.0  # s to wait for the CONFIG reply to one IDENTIFY


class RigClient:
    """Protocol client on a :class:`hw.link.SerialLink`.

    Parameters
    ----------
    url : str
        Serial port or pyserial URL.
    reply_timeout : float, optional
        Longest wait for a reply (s); keep it below the firmware watchdog.
    baudrate : int, optional
        Line speed (bit/s).
    """

    def __init__(self, url: str, reply_timeout: float = 0.05, baudrate: int = DEFAULT_BAUDRATE) -> None:
        reply_timeout = number(reply_timeout, "reply_timeout", low=0.0, high=1.0, low_open=True, unit="s")
        self.link = SerialLink(url, baudrate)
        self.reply_timeout = reply_timeout
        self.config: P.Config | None = None
        self.strict = False  # during an episode: any rejected byte or missing frame is an error
        self._rejected = 0
        self._gaps = 0
        self._pending_stop: P.StopReason | None = None

    @property
    def url(self) -> str:
        """The serial port or pyserial URL."""
        return self.link.url

    def close(self) -> None:
        """Close the serial link (the firmware's watchdog stops the motor)."""
        self.link.close()

    # ------------------------------------------------------------------ receiving
    def _check_link(self) -> None:
        st = self.link.parser.stats
        bad = st.rejected + st.garbage_bytes
        gaps = self.link.seq_gaps
        new_bad, new_gaps = bad - self._rejected, gaps - self._gaps
        self._rejected, self._gaps = bad, gaps
        if not self.strict:
            return
        if new_bad:
            raise LinkCorruptError(
                f"{self.url}: corrupted data from the firmware rejected "
                f"(CRC mismatches so far: {st.crc_errors}, malformed: {st.malformed}, "
                f"bytes outside frames: {st.garbage_bytes}); stopping"
            )
        if new_gaps:
            raise LinkSequenceError(
                f"{self.url}: {new_gaps} frame(s) from the firmware missing (sequence number gap); stopping"
            )

    def _stop_of(self, msg: P.EmergencyStop) -> P.StopReason:
        try:
            return P.StopReason(msg.reason)
        except ValueError:  # a protocol violation, not a bug of the host: a link fault (the motor is stopped)
            raise LinkCorruptError(
                f"{self.url}: EMERGENCY_STOP from the firmware with an unknown reason {msg.reason}; stopping"
            ) from None

    def _wait_for(self, want, what: str, sent: float, timeout: float | None = None) -> tuple[P.Message, float]:
        deadline = sent + (self.reply_timeout if timeout is None else timeout)
        while True:
            frames = self.link.receive(deadline)
            self._check_link()
            found = None
            for frame, t in frames:  # the whole batch: a stop sent right behind the wanted reply is kept
                msg = P.decode(frame)
                if isinstance(msg, P.EmergencyStop):
                    self._pending_stop = self._stop_of(msg)
                elif found is None and want(msg):
                    found = msg, t
            if found is not None:
                return found
            if time.monotonic() >= deadline:
                st = self.link.parser.stats
                version = (
                    f"; firmware speaks protocol version(s) {sorted(st.foreign_versions)}, host speaks "
                    f"{P.PROTOCOL_VERSION}"
                    if st.foreign_versions
                    else ""
                )
                raise LinkTimeoutError(
                    f"{self.url}: no {what} within {1e3 * (deadline - sent):.0f} ms "
                    f"(frame lost or late, or firmware not responding){version}"
                )

    # ------------------------------------------------------------------ commands
    def identify(self, period_s: float = 0.0, attempts: int = 3) -> P.Config:
        """Handshake: flush stale input, IDENTIFY, read CONFIG.

        Parameters
        ----------
        period_s : float, optional
            Control period to set in the firmware (s); 0 keeps the firmware's.
        attempts : int, optional
            IDENTIFY attempts before giving up.

        Returns
        -------
        hw.protocol.Config
            The firmware's configuration (protocol version, period, encoder and LVDT scales, limits).

        Raises
        ------
        LinkTimeoutError
            No CONFIG reply in any attempt.
        LinkError
            The firmware speaks another protocol version.
        """
        last: LinkError | None = None
        for _ in range(attempts):
            self.link.flush_input()
            self._check_link()
            sent = time.monotonic()
            self.link.send(P.Identify(int(round(period_s * 1e6))))
            try:
                # the motor is not driven during the handshake (the watchdog arms at the first command): a
                # loaded host may take its time (0.2 s per attempt failed under a cold test run)
                cfg, _ = self._wait_for(
                    lambda m: isinstance(m, P.Config),
                    "CONFIG reply to IDENTIFY",
                    sent,
                    max(self.reply_timeout, HANDSHAKE_TIMEOUT_S),
                )
            except LinkTimeoutError as exc:
                last = exc
                continue
            if cfg.protocol_version != P.PROTOCOL_VERSION:
                raise LinkError(
                    f"{self.url}: firmware protocol version {cfg.protocol_version}, host speaks {P.PROTOCOL_VERSION}"
                )
            self.config = cfg
            return cfg
        raise last  # type: ignore[misc]

    def clear_stop(self) -> None:
        """Clear a latched stop (answered by ACK)."""
        self._pending_stop = None
        sent = time.monotonic()
        seq = self.link.send(P.ClearStop())
        self._wait_for(lambda m: isinstance(m, P.Ack) and m.acked_seq == seq, "ACK of CLEAR_STOP", sent)

    def exchange(self, volts: float) -> Reply:
        """Send a voltage and read the SAMPLE answering it.

        Parameters
        ----------
        volts : float
            Motor voltage (V) for the next control period (the firmware clamps and slew-limits it too).

        Returns
        -------
        Reply
            The SAMPLE (the rig's state at the end of that control period), the host's send and receive
            times (s, ``time.monotonic``) and a stop the firmware reported with it.

        Raises
        ------
        LinkTimeoutError
            No SAMPLE within ``reply_timeout``.
        """
        sent = time.monotonic()
        seq = self.link.send(P.SetVoltage(float(volts)))
        sample, t = self._wait_for(
            lambda m: isinstance(m, P.Sample) and m.ack_seq == seq, f"SAMPLE reply to SET_VOLTAGE seq {seq}", sent
        )
        stop, self._pending_stop = self._pending_stop, None
        return Reply(sample, sent, t, stop)

    def stop_reason(self, wait_s: float = 0.05) -> P.StopReason | None:
        """The reason of a stop the firmware reported (EMERGENCY_STOP), or None.

        A stop tripped at the end of a period is sent right after that period's SAMPLE.

        Parameters
        ----------
        wait_s : float, optional
            Longest wait for the report (s).
        """
        deadline = time.monotonic() + wait_s
        while self._pending_stop is None and time.monotonic() < deadline:
            try:
                self._wait_for(lambda m: False, "EMERGENCY_STOP", time.monotonic(), 0.005)
            except LinkTimeoutError:
                pass
        stop, self._pending_stop = self._pending_stop, None
        return stop

    def heartbeat(self, token: int) -> float:
        """Round trip (s) of a HEARTBEAT carrying ``token`` (an unsigned 32-bit value)."""
        sent = time.monotonic()
        self.link.send(P.Heartbeat(token & 0xFFFFFFFF))
        _, t = self._wait_for(lambda m: isinstance(m, P.Heartbeat) and m.token == token, "HEARTBEAT echo", sent)
        return t - sent

    def emergency_stop(self, wait: bool = False, attempts: int = 1) -> int:
        """Ask the firmware to stop the motor (0 V, latched).

        Parameters
        ----------
        wait : bool, optional
            False (default): send it once and return 0 (fire and forget; the watchdog is the fallback).
            True: send it until the firmware acknowledges it.
        attempts : int, optional
            With ``wait``: the most times it is sent (each attempt waits ``reply_timeout``).

        Returns
        -------
        int
            The attempt the firmware acknowledged (1-based), or 0 without ``wait``.

        Raises
        ------
        LinkTimeoutError
            With ``wait``: no attempt was acknowledged.
        """
        if not wait:
            self.link.send(P.EmergencyStop(int(P.StopReason.HOST)))
            return 0
        last: LinkTimeoutError | None = None
        for k in range(1, max(1, attempts) + 1):
            sent = time.monotonic()
            seq = self.link.send(P.EmergencyStop(int(P.StopReason.HOST)))
            try:
                self._wait_for(
                    lambda m, seq=seq: isinstance(m, P.Ack) and m.acked_seq == seq, "ACK of EMERGENCY_STOP", sent
                )
                return k
            except LinkTimeoutError as exc:
                last = exc
        raise last  # type: ignore[misc]
