"""The rig emulator: the emulated firmware behind a real pseudo-terminal, in real time.

:class:`RigEmulator` opens a pseudo-terminal (``os.openpty``), gives the host the slave
device (``.port``, optionally also a symlink) and runs two threads:

* the serial thread (the firmware's main loop): reads bytes, parses frames, lets the
  :class:`hw.firmware.Firmware` execute them and writes the replies after the configured
  serial latency and jitter, injecting the faults of a :class:`FaultPlan`;
* the timer thread (the microcontroller's hardware timer): the watchdog and the plant
  running on in real time while the link is idle.  It keeps working when the serial thread
  is killed (:meth:`RigEmulator.kill`) or the link is unplugged (:meth:`RigEmulator.unplug`).

Every change of the motor voltage is logged (``firmware.events``, wall-clock times), so a
test can assert when the motor reached 0 V after a fault (:meth:`RigEmulator.zero_delay`).
"""

from __future__ import annotations

import heapq
import os
import random
import select
import threading
import time
import tty
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drillgym import RigParams
from drillgym.errors import OutputPathError
from drillgym.io import create_directory

from . import protocol as P
from .checks import number
from .firmware import Firmware, FirmwareConfig
from .timing import DurationStats, GcPauses

__all__ = ["FaultPlan", "RigEmulator"]


@dataclass
class FaultPlan:
    """Link faults to inject, by the index (1-based) of the SET_VOLTAGE they concern.

    Parameters
    ----------
    corrupt_sample : int, optional
        Flip a byte in the SAMPLE answering that command.
    drop_command : int, optional
        That command never reaches the firmware.
    drop_sample : int, optional
        Its SAMPLE never reaches the host.
    delay_command : int, optional
        That command (and everything behind it on the line) arrives ``delay_s`` late.
    delay_s : float, optional
        The delay of ``delay_command`` (s).  Default 0.2.
    """

    corrupt_sample: int | None = None
    drop_command: int | None = None
    drop_sample: int | None = None
    delay_command: int | None = None
    delay_s: float = 0.2


@dataclass
class _Timed:
    due: float
    order: int
    data: object = field(compare=False)  # bytes to send, or a held Frame
    since: float = field(default=0.0, compare=False)  # a SAMPLE answering a command: when the command was read

    def __lt__(self, other: _Timed) -> bool:
        return (self.due, self.order) < (other.due, other.order)


def check_link_path(path: Path) -> None:
    """Refuse a link path whose use would replace something the user did not ask to replace.

    The emulator links ``path`` to its pseudo-terminal. A link left by an earlier emulator (one that
    points into ``/dev/pts``, or a dangling one) is replaced; anything else is refused before the
    pseudo-terminal opens.

    Parameters
    ----------
    path : pathlib.Path
        The ``--port`` path of ``drillgym rig emulate``.

    Raises
    ------
    OutputPathError
        ``path`` is a file, a directory, or a link to something other than a pseudo-terminal.
    """
    if path.is_symlink():
        target = os.readlink(path)
        if target.startswith("/dev/pts/") or not path.exists():
            return
        raise OutputPathError(
            f"--port {path}: is a link to {target}, not to a pseudo-terminal; choose another path for the link"
        )
    if path.exists():
        kind = "a directory" if path.is_dir() else "a file"
        raise OutputPathError(
            f"--port {path}: exists ({kind}); the emulator would replace it by a link to its pseudo-terminal: "
            "choose another path or remove it yourself"
        )


class RigEmulator:
    """Emulated rig on a pseudo-terminal (see the module docstring).

    Parameters
    ----------
    configuration : str, optional
        Rig configuration of the plant ('torsional', 'lateral', 'coupled', ...).
    params : RigParams, optional
        Base parameters of the plant (default the identified set).
    firmware : FirmwareConfig, optional
        Firmware settings (encoder resolution, LVDT scale, period, watchdog, limits).
    effects : object, optional
        Hidden effects of the plant (as :func:`drillgym.simulate`'s ``effects``).
    effect_params : mapping, optional
        Their parameter values by name (defaults: each Parameter's).
    dt : float, optional
        Integration step of the plant (s).
    method : str, optional
        Integration method of the plant ('rk4', 'dp5').
    alpha0 : float, optional
        Initial winding of the string (rad), rig at rest.
    lvdt_noise_std : float, optional
        LVDT noise (m, standard deviation).
    seed : int or None, optional
        Seed of the LVDT noise.
    latency_s : float, optional
        Serial latency of every reply (s).
    jitter_s : float, optional
        Extra latency drawn uniformly from [0, jitter_s] (s).
    faults : FaultPlan, optional
        Link faults to inject.
    link_path : str or path, optional
        Also create a symlink to the pseudo-terminal there (removed on stop).
    log : callable, optional
        ``log(message: str)``, told of connections (IDENTIFY), stops (with their reason), cleared stops and a lost link,
        e.g. ``drillgym rig emulate`` prints them with a time stamp.
    """

    def __init__(
        self,
        configuration: str = "torsional",
        params: RigParams | None = None,
        firmware: FirmwareConfig | None = None,
        *,
        effects: Any = None,
        effect_params: Mapping[str, float] | None = None,
        dt: float = 1e-3,
        method: str = "rk4",
        alpha0: float = 0.0,
        lvdt_noise_std: float = 0.0,
        seed: int | None = 0,
        latency_s: float = 0.0,
        jitter_s: float = 0.0,
        faults: FaultPlan | None = None,
        link_path: str | Path | None = None,
        log=None,
    ) -> None:
        latency_s = number(latency_s, "latency_s", low=0.0, high=60.0, unit="s")
        jitter_s = number(jitter_s, "jitter_s", low=0.0, high=60.0, unit="s")
        self.firmware = Firmware(
            configuration,
            params,
            firmware,
            effects=effects,
            effect_params=effect_params,
            dt=dt,
            method=method,
            alpha0=alpha0,
            lvdt_noise_std=lvdt_noise_std,
            seed=seed,
        )
        self.firmware.on_log = log
        self.latency_s = float(latency_s)
        self.jitter_s = float(jitter_s)
        self.faults = faults or FaultPlan()
        self.link_path = Path(link_path) if link_path else None
        self._jrng = random.Random(seed)
        self._lock = threading.RLock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._io_dead = threading.Event()
        self._tx: list[_Timed] = []
        self._rx_held: list[_Timed] = []
        self._order = 0
        self._commands = 0
        self._last_tx_due = 0.0
        self._master: int | None = None
        self._slave: int | None = None
        self.port: str | None = None
        self.fault_times: dict[str, float] = {}
        self._threads: list[threading.Thread] = []
        self.errors: list[BaseException] = []
        self._rx_busy = False  # the serial thread holds bytes it has read but not executed yet
        #: command read -> its SAMPLE written to the pseudo-terminal (s), configured latency included
        self.service = DurationStats()
        #: work of one serial-loop pass (read, parse, execute, write; s), waiting excluded
        self.serial_work = DurationStats()
        #: how late the timer thread woke after its planned wait (s)
        self.timer_late = DurationStats()
        self.gc_pauses = GcPauses()

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> str:
        """Open the pseudo-terminal, start the threads; returns the device path for the host."""
        if self._threads:
            raise RuntimeError("emulator already started")
        if self.link_path is not None:
            check_link_path(self.link_path)
            create_directory(self.link_path.parent, for_path=self.link_path)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line discipline: a byte pipe like a UART
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        if self.link_path is not None:
            try:
                if self.link_path.is_symlink() or self.link_path.exists():
                    self.link_path.unlink()
                self.link_path.symlink_to(self.port)
            except OSError as exc:
                os.close(self._master)
                os.close(self._slave)
                raise OutputPathError(
                    f"{self.link_path}: cannot link it to the pseudo-terminal {self.port} ({exc.strerror})"
                ) from None
        self._threads = [
            threading.Thread(target=self._guard, args=(self._serial_loop,), name="rig-serial", daemon=True),
            threading.Thread(target=self._guard, args=(self._timer_loop,), name="rig-timer", daemon=True),
        ]
        self.gc_pauses.install()
        for t in self._threads:
            t.start()
        return str(self.link_path) if self.link_path is not None else self.port

    def stop(self) -> None:
        """Stop the threads, close the pseudo-terminal, remove the symlink."""
        self._stop.set()
        self._wake.set()
        for t in self._threads:
            t.join(timeout=2.0)
        for fd in (self._master, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = None
        self.gc_pauses.remove()
        if self.link_path is not None and self.link_path.is_symlink() and os.readlink(self.link_path) == self.port:
            self.link_path.unlink()  # our own link only: another emulator may have taken the path since

    def __enter__(self) -> RigEmulator:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def serve_forever(self) -> None:
        """Run until interrupted (Ctrl-C) or a thread fails."""
        try:
            while not self._stop.is_set():
                time.sleep(0.2)
        finally:
            self.stop()
        if self.errors:
            raise self.errors[0]

    # ------------------------------------------------------------------ faults
    def kill(self) -> float:
        """The firmware's main loop dies: no more serial I/O (the timer/watchdog keeps running).
        Returns the fault time (time.monotonic)."""
        t = time.monotonic()
        self.fault_times["kill"] = t
        self._io_dead.set()
        self._wake.set()
        return t

    def unplug(self) -> float:
        """The serial cable is pulled: the pseudo-terminal's master side is closed (the host's reads
        and writes fail); the firmware sees the detach (as a USB-CDC device does) and stops the motor
        (StopReason.LINK_LOST), then keeps running.  Returns the fault time (time.monotonic)."""
        t = time.monotonic()
        self.fault_times["unplug"] = t
        self._io_dead.set()
        with self._lock:
            if self._master is not None:
                os.close(self._master)
                self._master = None
            self.firmware.link_lost(t)
        return t

    def zero_delay(self, since: float) -> float | None:
        """Seconds from ``since`` (time.monotonic) until the motor was at 0 V (0 if it already was),
        or None if it never was."""
        with self._lock:
            events = list(self.firmware.events)
        before = [e for e in events if e.time <= since]
        if before and before[-1].volts == 0.0 or not events:
            return 0.0
        after = [e for e in events if e.time > since and e.volts == 0.0]
        return after[0].time - since if after else None

    def timing_summary(self) -> str:
        """One line of the emulator's own timing since start: how long it took to answer a command (read ->
        SAMPLE written), its longest serial-loop pass, its timer thread's latest wake-up, its GC pauses."""
        return (
            f"{self.service.count} commands served; service time {self.service.summary()}; "
            f"longest serial-loop pass {1e3 * self.serial_work.max:.2f} ms; "
            f"timer thread woke late by at most {1e3 * self.timer_late.max:.2f} ms; "
            f"garbage collector: {self.gc_pauses.summary()}"
        )

    @property
    def stats(self) -> dict:
        """Counts for tests and benchmarks."""
        fw = self.firmware
        return {
            "commands": fw.commands,
            "seq_gaps": fw.seq_gaps,
            "stop_reason": fw.stop_reason,
            "volts": fw.volts,
            "faults": dict(self.fault_times),
            "service_max_s": self.service.max,
            "gc_longest_s": self.gc_pauses.pauses.longest,
        }

    # ------------------------------------------------------------------ threads
    def _guard(self, loop) -> None:
        try:
            loop()
        except BaseException as exc:  # reported by serve_forever / tests
            self.errors.append(exc)
            self._stop.set()

    def _queue_tx(self, frames: list[bytes], now: float, index: int | None = None) -> None:
        for data in frames:
            since = now if index is not None and data[3] == P.MsgType.SAMPLE else 0.0
            if index is not None and data[3] == P.MsgType.SAMPLE:
                if self.faults.drop_sample == index:
                    self.fault_times["drop_sample"] = now
                    continue
                if self.faults.corrupt_sample == index:
                    self.fault_times["corrupt_sample"] = now
                    b = bytearray(data)
                    b[len(b) // 2] ^= 0x5A
                    data = bytes(b)
            due = now + self.latency_s + (self._jrng.uniform(0.0, self.jitter_s) if self.jitter_s else 0.0)
            due = max(due, self._last_tx_due)  # a UART keeps the order of bytes
            self._last_tx_due = due
            self._order += 1
            heapq.heappush(self._tx, _Timed(due, self._order, data, since))

    def _execute(self, frame: P.Frame, now: float) -> None:
        index = None
        if frame.type == P.MsgType.SET_VOLTAGE:
            self._commands += 1
            index = self._commands
        with self._lock:
            out = self.firmware.handle(frame, now)
            self._queue_tx(out, now, index)
        self._wake.set()

    def _serial_loop(self) -> None:
        parser = P.FrameParser()
        while not self._stop.is_set() and not self._io_dead.is_set():
            now = time.monotonic()
            timeout = 0.005
            if self._tx:
                timeout = min(timeout, max(0.0, self._tx[0].due - now))
            if self._rx_held:
                timeout = min(timeout, max(0.0, self._rx_held[0].due - now))
            with self._lock:
                master = self._master
            if master is None:
                return
            try:
                ready, _, _ = select.select([master], [], [], timeout)
                self._rx_busy = bool(ready)
                data = os.read(master, 4096) if ready else b""
            except (OSError, ValueError):
                return  # unplugged
            if self._io_dead.is_set():
                return  # killed while waiting: what arrived is never executed
            now = t_pass = time.monotonic()
            for frame in parser.feed(data) if data else ():
                self._receive(frame, now)
            self._rx_busy = False
            while self._rx_held and self._rx_held[0].due <= now:
                self._execute(heapq.heappop(self._rx_held).data, now)
            with self._lock:
                self._write_due(master, now)
            done = time.monotonic()
            self.serial_work.add(done - t_pass, done)

    def _receive(self, frame: P.Frame, now: float) -> None:
        nxt = self._commands + 1
        if frame.type == P.MsgType.SET_VOLTAGE and not self._rx_held:
            if self.faults.drop_command == nxt:
                self._commands += 1
                self.fault_times["drop_command"] = now
                return
            if self.faults.delay_command == nxt:
                self.fault_times["delay_command"] = now
        if self._rx_held or (frame.type == P.MsgType.SET_VOLTAGE and self.faults.delay_command == nxt):
            due = self._rx_held[-1].due if self._rx_held else now + self.faults.delay_s
            self._order += 1
            self._rx_held.append(_Timed(due, self._order, frame))
            return
        self._execute(frame, now)

    def _write_due(self, master: int, now: float) -> None:
        while self._tx and self._tx[0].due <= now:
            item = self._tx[0]
            try:
                n = os.write(master, item.data)
            except BlockingIOError:
                return  # host not reading: keep it for later
            except OSError:
                return
            if n < len(item.data):
                item.data = item.data[n:]
                return
            heapq.heappop(self._tx)
            if item.since:
                done = time.monotonic()
                self.service.add(done - item.since, done)

    def _rx_pending(self) -> bool:
        """Bytes from the host have arrived (in the pty or read by the serial thread) but are not executed yet:
        on a loaded machine the serial thread may be late, a microcontroller's receive interrupt is not."""
        if self._io_dead.is_set() or self._master is None:
            return False
        if self._rx_busy:
            return True
        try:
            return bool(select.select([self._master], [], [], 0)[0])
        except (OSError, ValueError):
            return False

    def _timer_loop(self) -> None:
        fw = self.firmware
        while not self._stop.is_set():
            now = time.monotonic()
            with self._lock:
                out = fw.poll(now, rx_pending=self._rx_pending())
                if out and not self._io_dead.is_set():
                    self._queue_tx(out, now)
                deadline = fw.watchdog_deadline()
            wait = fw.period_s if deadline is None else min(fw.period_s, deadline - time.monotonic())
            if wait > 0.002:
                planned = time.monotonic() + wait - 0.001
                woken = self._wake.wait(wait - 0.001)  # wake early, then close in on the deadline in small sleeps
                self._wake.clear()
            elif wait > 0:
                planned = time.monotonic() + min(wait, 2e-4)
                woken = False
                time.sleep(min(wait, 2e-4))
            else:
                continue
            if not woken:
                t = time.monotonic()
                self.timer_late.add(max(t - planned, 0.0), t)
