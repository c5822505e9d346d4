"""The rig's microcontroller, emulated: protocol handling, safety, watchdog, and the plant.

The plant is the core simulator (:class:`drillgym.BatchSimulator`, one rig) running the
composition of hidden effects (:mod:`drillgym.effects`: names, ``file.py:NAME``, classes or
instances, with their values), so the emulator, the environments and the single-run simulator
integrate the same compiled model (an input delay is the kernels' per-trajectory delay line).
It is measured the way the rig measures it: the composition's Measurement effects (LVDT
offset/skew, any user effect), then quantized encoders and LVDT noise (:mod:`drillgym.measurement`).

Stepping is deterministic: every SET_VOLTAGE advances the plant by exactly one control
period at the (safety-limited) voltage and is answered by the SAMPLE at the end of that
period.  When the link is idle (before the first command, or after a stop) the plant runs
on in real time at 0 V (:meth:`Firmware.poll`).  The watchdog stops the motor when no
SET_VOLTAGE has arrived for ``watchdog_s``.

The firmware knows nothing about threads or serial ports: :meth:`Firmware.handle` takes a
frame and the wall-clock time and returns the frames to send back (see :mod:`hw.emulator`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym import BatchSimulator, RigParams
from drillgym.errors import InputError
from drillgym.measurement import EncoderVelocityEstimator, angle_to_counts, counts_to_angle, lvdt_measure

from . import protocol as P
from .checks import integer, number
from .safety import SafetyLimits, VoltageLimiter, check_limits

__all__ = ["FirmwareConfig", "Firmware", "VoltageEvent", "EVENTS_KEPT"]

#: the voltage changes kept in ``Firmware.events`` (the latest; 20 s at 2 ms): a list growing by one object per
#: command made the emulator's garbage collector scan an ever larger heap, up to pauses longer than the watchdog
EVENTS_KEPT = 10_000

_I32 = 1 << 32


def _wrap_i32(v: int) -> int:
    """Two's-complement 32-bit wrap of a counter (as the microcontroller's registers do)."""
    return ((int(v) + (1 << 31)) % _I32) - (1 << 31)


@dataclass(frozen=True)
class FirmwareConfig:
    """Settings of the (emulated) firmware.

    Parameters
    ----------
    counts_per_rev : int, optional
        Encoder resolution (counts per revolution).  Default 8000.
    lvdt_m_per_lsb : float, optional
        LVDT scale (m per raw count).  Default 1e-7.
    control_period_s : float, optional
        Default control period (s); the host may change it with IDENTIFY.  Default 0.01.
    watchdog_s : float, optional
        The motor goes to 0 V after this long without SET_VOLTAGE (s).  Default 0.1.
    limits : SafetyLimits, optional
        The firmware's own safety limits.
    firmware_id : str, optional
        Identifier sent in CONFIG (at most 16 ASCII characters).
    """

    counts_per_rev: int = 8000
    lvdt_m_per_lsb: float = 1e-7
    control_period_s: float = 0.01
    watchdog_s: float = 0.1
    limits: SafetyLimits = field(default_factory=SafetyLimits)
    firmware_id: str = "drillgym-emu"

    def __post_init__(self) -> None:
        if not (isinstance(self.counts_per_rev, int) and self.counts_per_rev > 0):
            raise InputError(f"counts_per_rev must be a positive integer, got {self.counts_per_rev!r}")
        for name in ("lvdt_m_per_lsb", "control_period_s", "watchdog_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be > 0, got {v!r}")
        if not 1e-3 <= self.watchdog_s <= 65.535:
            raise InputError(f"watchdog_s must be in [0.001, 65.535] s (in whole ms), got {self.watchdog_s!r}")
        if self.control_period_s > 60.0:
            raise InputError(f"control_period_s must be at most 60 s, got {self.control_period_s!r}")
        if len(self.firmware_id.encode("ascii")) > 16:
            raise InputError(f"firmware_id must be at most 16 ASCII characters, got {self.firmware_id!r}")


@dataclass(frozen=True)
class VoltageEvent:
    """The motor voltage changed: wall-clock time (s, time.monotonic), voltage (V), why."""

    time: float
    volts: float
    cause: str


class Firmware:
    """The emulated microcontroller on the rig.

    Parameters
    ----------
    configuration : str, optional
        Rig configuration ('torsional', 'lateral', 'coupled', ...).
    params : RigParams, optional
        Base parameters of the plant (default the identified set).
    config : FirmwareConfig, optional
        Firmware settings.
    effects : object, optional
        Hidden effects of the plant (as :func:`drillgym.simulate`'s ``effects``).
    effect_params : mapping, optional
        Their parameter values by name (defaults: each Parameter's).
    dt : float, optional
        Integration step of the plant (s); must divide every control period.
    method : str, optional
        Integration method of the plant ('rk4', 'dp5').
    alpha0 : float, optional
        Initial winding of the string (rad), rig at rest.
    lvdt_noise_std : float, optional
        LVDT noise (m, standard deviation).
    seed : int or None, optional
        Seed of the LVDT noise.
    """

    def __init__(
        self,
        configuration: str = "torsional",
        params: RigParams | None = None,
        config: FirmwareConfig | None = None,
        *,
        effects: Any = None,
        effect_params: Mapping[str, float] | None = None,
        dt: float = 1e-3,
        method: str = "rk4",
        alpha0: float = 0.0,
        lvdt_noise_std: float = 0.0,
        seed: int | None = 0,
    ) -> None:
        lvdt_noise_std = number(lvdt_noise_std, "lvdt_noise_std", low=0.0, high=1.0, unit="m")
        alpha0 = number(alpha0, "alpha0", low=-100.0, high=100.0, unit="rad")
        if seed is not None:
            integer(seed, "seed", low=0)
        self.params = params or RigParams()
        self.config = config or FirmwareConfig()
        self.sim = BatchSimulator(
            configuration, 1, params=self.params, dt=dt, method=method, effects=effects, effect_params=effect_params
        )
        self.composition = self.sim.composition
        self.sim.reset(alpha0=alpha0)
        self.sim.advance(np.zeros(1), 0)  # load the compiled kernel now, not at the first command
        self.lvdt_noise_std = float(lvdt_noise_std)
        self._rng = np.random.default_rng(seed)
        self.limiter = VoltageLimiter(self.config.limits)
        self.n_sub = self._substeps(self.config.control_period_s)
        self._speed = EncoderVelocityEstimator(2, self.period_s, tau=0.0)
        self._speed.reset(self._angles())
        self.volts = 0.0
        self.stop_reason: P.StopReason | None = None
        self.armed = False  # a SET_VOLTAGE arrived since the last (re)start: watchdog running
        self.last_command: float | None = None
        self._idle_anchor: float | None = None
        self._tx_seq = 0
        self._rx_seq: int | None = None
        self.seq_gaps = 0
        self._gap_flag = False
        self.events: deque[VoltageEvent] = deque(maxlen=EVENTS_KEPT)
        self.commands = 0
        self.on_log = None  # callable(str): connections, stops and clears, for an operator's log

    # ------------------------------------------------------------------ configuration
    @property
    def period_s(self) -> float:
        """Control period (s), a whole number of plant steps."""
        return self.n_sub * self.sim.dt

    def _substeps(self, period_s: float) -> int:
        n = int(round(period_s / self.sim.dt))
        if n < 1 or abs(n * self.sim.dt - period_s) > 1e-9:
            raise InputError(f"control period {period_s} s is not a multiple of the plant step {self.sim.dt} s")
        return n

    def config_message(self) -> P.Config:
        """The CONFIG reply to IDENTIFY: protocol version, encoder and LVDT scales, period, limits, id."""
        c, lim = self.config, self.config.limits
        return P.Config(
            P.PROTOCOL_VERSION,
            c.counts_per_rev,
            c.lvdt_m_per_lsb,
            int(round(self.period_s * 1e6)),
            int(round(c.watchdog_s * 1e3)),
            lim.v_max,
            lim.slew_v_per_s,
            lim.max_speed,
            lim.max_displacement,
            c.firmware_id.encode("ascii"),
        )

    @property
    def effect_values(self) -> dict[str, float]:
        """The hidden effects' parameter values by name."""
        return self.composition.split(self.sim.P[0])[1]

    # ------------------------------------------------------------------ measurement
    def _channels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """theta_u, theta_l (rad), X, Y (m, fixed frame) of the plant as the sensors read them (the
        composition's Measurement effects applied), before quantization and noise; arrays (1,)."""
        X, Y = self.sim.lateral_fixed
        Y8 = self.sim.Y
        return self.composition.measure(Y8[:, 0], Y8[:, 1], X, Y, self.sim.P[0], Y8[:, 2], Y8[:, 3])

    def _counts(self) -> np.ndarray:
        """Encoder counts (int64, 2) of the measured angles."""
        tu, tl, _, _ = self._channels()
        return angle_to_counts(np.concatenate([tu, tl]), self.config.counts_per_rev)

    def _angles(self) -> np.ndarray:
        """Encoder angles (rad) as the firmware sees them (quantized)."""
        return counts_to_angle(self._counts(), self.config.counts_per_rev)

    def _lvdt(self) -> tuple[float, float]:
        """LVDT readings (m): measured X, Y plus white noise of ``lvdt_noise_std``."""
        _, _, X, Y = self._channels()
        xm, ym = lvdt_measure(X, Y, self.lvdt_noise_std, self._rng)
        return float(xm[0]), float(ym[0])

    # ------------------------------------------------------------------ plant
    def _set_volts(self, u: float, now: float, cause: str) -> None:
        if u != self.volts or not self.events:
            self.events.append(VoltageEvent(now, u, cause))
        self.volts = u

    def _advance_period(self, u: float) -> None:
        """One control period of the plant at u (V, already safety-limited); a hidden input delay
        acts inside the kernels (their delay line), as in every other simulation path."""
        self.sim.advance(np.array([u]), self.n_sub)

    def _after_period(self, now: float, emit: bool = True) -> list[bytes]:
        """Safety checks at the end of a period (once per period: they update the speed estimate); the
        frames to send if a stop trips (none with ``emit=False``: the caller sends them in sequence)."""
        omega = self._speed.update(self._angles())
        x, y = self._lvdt()
        reason = check_limits(self.config.limits, float(omega[0]), float(omega[1]), x, y)
        if reason is not None and self.stop_reason is None:
            return self._stop(reason, now, emit)
        return []

    def _log(self, message: str) -> None:
        if self.on_log is not None:
            self.on_log(message)

    def _stop(self, reason: P.StopReason, now: float, emit: bool = True) -> list[bytes]:
        self._log(
            f"motor stopped (0 V, latched): {P.StopReason(reason).name}"
            + (
                f" (no command for {1e3 * (now - self.last_command):.0f} ms)"
                if reason == P.StopReason.WATCHDOG and self.last_command is not None
                else ""
            )
        )
        self.stop_reason = P.StopReason(reason)
        self.armed = False
        self.limiter.reset(0.0)
        self._set_volts(0.0, now, reason.name.lower())
        self._idle_anchor = now
        return [self._frame(P.EmergencyStop(int(reason)))] if emit else []

    def _frame(self, msg: P.Message) -> bytes:
        seq = self._tx_seq
        self._tx_seq = (self._tx_seq + 1) & 0xFFFF
        return P.encode(msg, seq)

    def sample(self, ack_seq: int, limited: bool = False) -> P.Sample:
        """The SAMPLE of the plant's current state."""
        cu, cl = (int(c) for c in self._counts())
        x, y = self._lvdt()
        s = self.config.lvdt_m_per_lsb
        status = P.Status.OK
        if self.stop_reason is not None:
            status |= P.Status.STOPPED
            if self.stop_reason == P.StopReason.WATCHDOG:
                status |= P.Status.WATCHDOG
        if limited:
            status |= P.Status.LIMITED
        if self._gap_flag:
            status |= P.Status.SEQ_GAP
            self._gap_flag = False
        return P.Sample(
            ack_seq & 0xFFFF,
            int(round(float(self.sim.T[0]) * 1e6)),
            _wrap_i32(cu),
            _wrap_i32(cl),
            _wrap_i32(round(x / s)),
            _wrap_i32(round(y / s)),
            self.volts,
            int(status),
        )

    # ------------------------------------------------------------------ protocol
    def handle(self, frame: P.Frame, now: float) -> list[bytes]:
        """Execute one received frame at wall-clock time ``now`` (s); the frames to send back."""
        if self._rx_seq is not None and frame.seq != self._rx_seq:
            self.seq_gaps += 1
            self._gap_flag = True
        self._rx_seq = (frame.seq + 1) & 0xFFFF
        try:
            msg = P.decode(frame)
        except P.ProtocolError:
            return []
        if isinstance(msg, P.SetVoltage):
            return self._on_set_voltage(msg, frame.seq, now)
        if isinstance(msg, P.Heartbeat):
            return [self._frame(msg)]
        if isinstance(msg, P.Identify):
            self._log(
                "host connected: IDENTIFY" + (f" (control period {msg.period_us / 1e3:g} ms)" if msg.period_us else "")
            )
            if msg.period_us:
                try:
                    n = self._substeps(msg.period_us * 1e-6)
                except ValueError:
                    n = self.n_sub  # refused: the CONFIG reply tells the host the period in force
                if n != self.n_sub:
                    self.n_sub = n
                    self._speed = EncoderVelocityEstimator(2, self.period_s, tau=0.0)
                    self._speed.reset(self._angles())
            return [self._frame(self.config_message())]
        if isinstance(msg, P.EmergencyStop):
            if self.stop_reason is not None:
                self._log(f"emergency stop from the host (already stopped: {self.stop_reason.name})")
            out = self._stop(P.StopReason.HOST, now) if self.stop_reason is None else []
            return out + [self._frame(P.Ack(frame.type, frame.seq))]
        if isinstance(msg, P.ClearStop):  # clear a latched stop; idle: 0 V, watchdog disarmed
            if self.stop_reason is not None:
                self._log(f"stop cleared by the host ({self.stop_reason.name}); idle at 0 V")
            self.stop_reason = None
            self.armed = False
            self._idle_anchor = now
            self.limiter.reset(0.0)
            self._set_volts(0.0, now, "idle")
            self._speed.reset(self._angles())
            return [self._frame(P.Ack(frame.type, frame.seq))]
        return []  # a firmware->host type sent to the firmware: ignored

    def _on_set_voltage(self, msg: P.SetVoltage, seq: int, now: float) -> list[bytes]:
        self.commands += 1
        out: list[bytes] = []
        limited = False
        if self.stop_reason is None:
            u, limited = self.limiter.limit(msg.volts, self.period_s)
            self.armed = True
            self.last_command = now
            self._set_volts(u, now, "command")
        self._advance_period(self.volts)
        was_stopped = self.stop_reason is not None
        self._after_period(now, emit=False)
        out.append(self._frame(self.sample(seq, limited)))  # the SAMPLE, then the stop it tripped, in sequence
        if self.stop_reason is not None and not was_stopped:
            out.append(self._frame(P.EmergencyStop(int(self.stop_reason))))
        if self.stop_reason is not None:
            self._idle_anchor = now
        return out

    def poll(self, now: float, rx_pending: bool = False) -> list[bytes]:
        """Time passes (wall clock ``now``, s): the watchdog, and the plant running on while idle.

        ``rx_pending``: bytes have arrived at the UART that the main loop has not parsed yet.  The
        watchdog counts the time since the last command *received*; a command waiting in the receive
        buffer has been (a microcontroller's receive interrupt would have taken it), so the stop waits
        until the main loop has parsed it, at most one more watchdog period."""
        out: list[bytes] = []
        late = None if self.last_command is None else now - self.last_command
        if (
            self.armed
            and late is not None
            and late >= self.config.watchdog_s
            and not (rx_pending and late < 2 * self.config.watchdog_s)
        ):
            # A microcontroller's watchdog is a hardware timer: it fires at its deadline, however late
            # this poll comes (the emulator's timer thread can be starved on a loaded host).  A stop held
            # back by a pending command happens when it is decided, now.
            at = now if rx_pending else self.last_command + self.config.watchdog_s
            out += self._stop(P.StopReason.WATCHDOG, at)
        if self.armed:
            return out
        if self._idle_anchor is None:
            self._idle_anchor = now
        k = int((now - self._idle_anchor) / self.period_s)
        for _ in range(k):
            self._advance_period(self.volts)
            out += self._after_period(now)
        self._idle_anchor += k * self.period_s
        return out

    def link_lost(self, now: float) -> None:
        """The serial link went down (a USB-CDC device sees the detach): stop the motor now."""
        self._log("link lost (port closed)")
        if self.stop_reason is None:
            self._stop(P.StopReason.LINK_LOST, now)

    def watchdog_deadline(self) -> float | None:
        """Wall-clock time (s) at which the watchdog trips if no command comes, or None."""
        if self.armed and self.last_command is not None:
            return self.last_command + self.config.watchdog_s
        return None
