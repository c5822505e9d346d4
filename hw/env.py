"""``drillgym/Hardware-v0``: the speed-tracking task on the physical rig (or its emulator).

Same action and observation spaces, reward, task and info keys as the simulated envs
(:mod:`drillgym.envs`; their observation models, reward, task and stick-slip monitor are
reused, fed with measurements instead of simulated states).  Differences forced by
hardware:

* real-time pacing at the control period (:class:`hw.pacing.Pacer`);
* measurements: encoder counts -> rad, LVDT offset taken at rest, 5 Hz causal low-pass
  (:mod:`hw.measurements`); speeds are encoder estimates (also in the 'full' observation,
  and in the reward and the termination test); ``friction_torque`` is not measurable (NaN);
* ``reset`` brings the rig to rest at 0 V (until the encoders stop moving) instead of
  setting a state; the initial winding is whatever the rig has;
* a safety layer no caller can bypass (:mod:`hw.safety`): every voltage is clamped to
  +/- 5 V and slew-limited before it leaves, over-speed / over-displacement stop the motor,
  the firmware repeats all of it and has a watchdog; every episode end, fault and ``close()``
  leaves the motor at 0 V;
* every episode is recorded (:mod:`hw.recording`), flushed at least every 0.5 s;
* an action beyond the amplifier range is clamped to +/- 5 V (as in the simulated envs) and the
  step's info says so: ``info["clamped_from"]`` = the voltage asked for.

A link fault (corrupted or missing frame, no reply, lost port) raises a
:class:`hw.link.LinkError` (a :class:`drillgym.errors.SafetyError`) after asking the firmware
to stop and closing the recording; call ``reset()`` to start again.
"""

from __future__ import annotations

import math
import time
import weakref
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.envs.action import action_voltage
from drillgym.envs.base import action_space
from drillgym.envs.observation import make_observation_model
from drillgym.envs.options import U_MAX, EnvOptions
from drillgym.envs.reward import TrackingReward
from drillgym.envs.task import SpeedTrackingTask, StickSlipMonitor
from drillgym.errors import InputError, InputTypeError, SafetyError

from . import protocol as P
from .checks import check_port, check_record_path, integer, number
from .client import Reply, RigClient
from .link import DEFAULT_BAUDRATE, LinkError, LinkLostError, LinkTimeoutError
from .measurements import RigMeasurements
from .pacing import Pacer
from .recording import EpisodeRecorder, RecordingError, episode_path
from .safety import SafetyLimits, VoltageLimiter, check_limits

__all__ = ["HardwareEnv", "HARDWARE_FIXED_OPTIONS"]

#: EnvOptions that describe the simulated plant; on hardware they are properties of the rig.
HARDWARE_FIXED_OPTIONS = (
    "params",
    "randomize",
    "randomize_names",
    "effects",
    "effect_params",
    "dt",
    "method",
    "friction",
    "alpha0_range",
    "lvdt_noise_std",
    "counts_per_rev",
    "render_history",
)
_ROW0 = np.zeros(1, dtype=np.int64)
#: EMERGENCY_STOP sent this often at an episode's end until the firmware acknowledges it (each waits one reply
#: timeout); unacknowledged, the firmware watchdog stops the motor.
STOP_ATTEMPTS = 3


def _stop_motor(client: RigClient) -> None:
    """Best effort: ask the firmware to stop (the watchdog does it anyway), close the port."""
    try:
        if client.link.is_open:
            client.emergency_stop()
    except Exception:  # noqa: BLE001 - the link may be gone; the firmware watchdog stops the motor
        pass
    client.close()


class HardwareEnv(gym.Env):
    """The speed-tracking task on the physical rig (or its emulator) behind a serial port.

    Same task as :class:`drillgym.envs.DrillEnv`, paced in real time, on measurements, behind a safety
    layer no caller can bypass (see the module docstring for every difference).

    Parameters
    ----------
    port : str
        Serial device or pyserial URL of the rig's microcontroller (or ``drillgym rig emulate``).
    configuration : str, optional
        'torsional', 'lateral' or 'coupled' (how the rig is set up).
    record : str or path, optional
        Recording file (.csv; later episodes get ``_<k>`` suffixes) or directory.
    limits : SafetyLimits, optional
        Host safety limits (clamp, slew rate, over-speed, over-displacement).
    rest_time : float, optional
        The rig is at rest when no encoder count changed for this long (s).
    rest_timeout : float, optional
        Give up bringing the rig to rest after this long (s).
    reply_timeout : float, optional
        Longest wait for the firmware's reply (s); None: the firmware's watchdog period from its CONFIG (a reply
        later than that is useless: the firmware has stopped the motor by then), which keeps a loaded host from
        giving up on replies the firmware still honours.
    lvdt_cutoff_hz : float, optional
        Causal LVDT low-pass cut-off (Hz).
    flush_interval_s : float, optional
        Recording flush interval (s, <= 1).
    baudrate : int, optional
        Serial line speed.
    **options
        The simulated envs' options (:class:`drillgym.envs.EnvOptions`): observation, control_dt,
        normalize_action, omega_ref, omega_ref_range, episode_duration, max_speed, max_lateral, reward,
        ssi_window, velocity_filter_tau, motor_history.  Options of the simulated plant (``params``,
        ``effects``, ``dt``, ...) are refused: on hardware they are properties of the rig.

    Raises
    ------
    InputError
        Before the port is opened: an option of the simulated plant, an environment option out of range (as the
        simulated envs refuse it), a ``port`` that is no serial device, a ``record`` path that cannot be written
        (:func:`hw.checks.check_record_path`), a non-finite or out-of-range ``rest_time``, ``rest_timeout``,
        ``reply_timeout``, ``lvdt_cutoff_hz`` (up to half the control rate) or ``flush_interval_s``.  After the
        handshake: a control period the firmware refuses or not shorter than its watchdog.
    MissingFileError
        The serial device does not exist.

    Notes
    -----
    **Action space.** As :class:`drillgym.envs.DrillEnv`: the motor voltage, in [-1, 1] (x 5 V) with
    ``normalize_action=True``, else in V.  Every voltage is clamped to +/- 5 V and slew-limited
    (:class:`hw.safety.SafetyLimits`) before it leaves the host; ``info["clamped_from"]`` holds a voltage
    (V) asked for beyond the amplifier range.

    **Observation space.** As :class:`drillgym.envs.DrillEnv` for the same ``observation`` and
    configuration, built from measurements: encoder counts -> rad, LVDT offset taken at rest and
    low-passed at ``lvdt_cutoff_hz``; speeds are encoder estimates, also in the ``"full"`` observation.

    **Reward.** As :mod:`drillgym.envs.reward`, on the measured speeds and the applied voltage.

    **Starting state.** :meth:`reset` holds 0 V until no encoder count changes for ``rest_time`` (s);
    the initial winding is whatever the rig has.

    **Episode end.** Terminated when a speed or the lateral displacement exceeds the task's limits
    (``max_speed``, ``max_lateral``), or on a safety stop of the host or the firmware (over-speed,
    over-displacement, watchdog; ``info["safety_stop"]`` names it).  Truncated after
    ``episode_duration``.  Every episode end leaves the motor at 0 V and closes the episode's
    recording.  A link fault raises :class:`hw.link.LinkError` (a
    :class:`drillgym.errors.SafetyError`) after asking the firmware to stop.

    **Info.** The simulated envs' keys (``friction_torque`` is NaN: not measurable), ``clamped_from``
    and ``safety_stop`` when they apply; a terminated episode says why in ``termination`` (as the simulated envs).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        port: str,
        configuration: str = "torsional",
        *,
        record: str | Path = "recordings",
        limits: SafetyLimits | None = None,
        rest_time: float = 0.2,
        rest_timeout: float = 30.0,
        reply_timeout: float = 0.05,
        lvdt_cutoff_hz: float = 5.0,
        flush_interval_s: float = 0.5,
        baudrate: int = DEFAULT_BAUDRATE,
        **options: Any,
    ) -> None:
        fixed = sorted(set(options) & set(HARDWARE_FIXED_OPTIONS))
        if fixed:
            raise InputError(
                f"option(s) {fixed} do not apply to the hardware environment (properties of the rig or its firmware)"
            )
        # everything checked before the port is opened: the options as the simulated envs check them (the
        # firmware's encoder resolution is applied after the handshake), then the hardware's own arguments
        control_dt = number(options.get("control_dt", EnvOptions.control_dt), "control_dt", low=0.0, low_open=True)
        # the simulated envs' integration step does not apply (the firmware integrates nothing on the host's side)
        EnvOptions.from_kwargs(configuration=configuration, lvdt_noise_std=0.0, dt=control_dt, **options)
        self.port = check_port(port, "port")
        self.record = check_record_path(record, "record")
        if limits is not None and not isinstance(limits, SafetyLimits):
            raise InputTypeError(f"limits must be a hw.safety.SafetyLimits, got {type(limits).__name__}")
        self.rest_time = number(rest_time, "rest_time", low=0.0, low_open=True, unit="s")
        self.rest_timeout = number(rest_timeout, "rest_timeout", low=self.rest_time, low_open=True, unit="s")
        if reply_timeout is not None:
            reply_timeout = number(reply_timeout, "reply_timeout", low=0.0, high=1.0, low_open=True, unit="s")
        nyquist = 0.5 / control_dt
        self.lvdt_cutoff_hz = number(
            lvdt_cutoff_hz, "lvdt_cutoff_hz", low=0.0, high=nyquist, low_open=True, unit="Hz (half the control rate)"
        )
        self.flush_interval_s = number(flush_interval_s, "flush_interval_s", low=0.0, high=1.0, low_open=True, unit="s")
        integer(baudrate, "baudrate", low=1)
        self.limits = limits or SafetyLimits()
        self._reply_timeout, self._baudrate = reply_timeout, baudrate
        self._client = RigClient(self.port, 0.05 if reply_timeout is None else reply_timeout, baudrate)
        self._finalizer = weakref.finalize(self, _stop_motor, self._client)
        try:
            cfg = self._client.identify(control_dt)
            if reply_timeout is None:  # wait as long as the firmware keeps the motor going without a command
                self._reply_timeout = self._client.reply_timeout = min(cfg.watchdog_ms * 1e-3, 1.0)
            if abs(cfg.period_s - control_dt) > 1e-9:
                raise InputError(
                    f"the firmware on {self.port} runs a {cfg.period_s} s control period and refused {control_dt} s"
                )
            if control_dt >= cfg.watchdog_ms * 1e-3:
                raise InputError(
                    f"control_dt {control_dt:g} s is not shorter than the firmware's watchdog ({cfg.watchdog_ms} ms): "
                    "every period would stop the motor; use a shorter control period"
                )
            self.options = EnvOptions.from_kwargs(
                configuration=configuration,
                counts_per_rev=cfg.counts_per_rev,
                lvdt_noise_std=0.0,
                dt=control_dt,
                **options,
            )
        except BaseException:
            self._finalizer()
            raise
        self.firmware = cfg
        o = self.options
        self.action_space = action_space(o.normalize_action)
        self._scale = U_MAX if o.normalize_action else 1.0
        self.obs_model = make_observation_model(1, o)
        self.observation_space = self.obs_model.space
        self.task = SpeedTrackingTask(o)
        self.reward_fn = TrackingReward(o.reward)
        self.monitor = StickSlipMonitor(1, o.ssi_window, o.control_dt)
        self.limiter = VoltageLimiter(self.limits)
        self.pacer = Pacer(o.control_dt)
        self.measurements = RigMeasurements(
            cfg.counts_per_rev, cfg.lvdt_m_per_lsb, o.control_dt, o.velocity_filter_tau, self.lvdt_cutoff_hz
        )
        # measurements in the shape of the simulated envs' arrays (rows = rigs = 1)
        self._Y, self._MODE = self.measurements.Y, self.measurements.MODE  # the state as measured (mechanical states)
        self._obs = np.zeros((1, self.obs_model.dim), dtype=np.float32)
        self._reward = np.zeros(1)
        self._unsafe = np.zeros(1, dtype=bool)
        self._omega_ref = np.ones(1)
        self._u_prev = np.zeros(1)
        self._steps = 0
        self._episode = -1
        self._running = False
        self._fault: BaseException | None = None
        #: the last episode's end: True when the firmware acknowledged the EMERGENCY_STOP, False when it did not
        #: (the watchdog stops the motor), None before any episode ended
        self.stop_acknowledged: bool | None = None
        self.recorder: EpisodeRecorder | None = None
        self._pending: dict[str, float] | None = None  # the last sample, written once the next reply tells its voltage
        self.last_reply: Reply | None = None
        self._warm_up()

    def _warm_up(self) -> None:
        """Load the compiled kernels of reward, task and observation now: a first call inside
        an episode would take longer than the firmware's watchdog."""
        self.reward_fn(self._Y, self._MODE, self._u_prev, self._u_prev, self._omega_ref, self._reward)
        self.task.unsafe(self._Y, self._unsafe)
        self.monitor.update(self._Y[:, 3])
        self.obs_model.initial(_ROW0, self._Y, self._omega_ref)

    # ------------------------------------------------------------------ properties
    @property
    def observation_names(self) -> tuple[str, ...]:
        return self.obs_model.names

    @property
    def client(self) -> RigClient:
        """The protocol client of the link (heartbeats, firmware CONFIG)."""
        return self._client

    @property
    def recording(self) -> Path | None:
        """The current (or last) episode's recording file."""
        return self.recorder.path if self.recorder is not None else None

    # ------------------------------------------------------------------ link with fault handling
    def _exchange(self, volts: float) -> Reply:
        try:
            reply = self._client.exchange(volts)
        except LinkError as exc:
            self._on_fault(exc)
            kept = (
                f"recording kept up to the fault: {self.recording}"
                if self.recording is not None
                else "nothing recorded yet (the fault came before the episode's first sample, while the rig was "
                "brought to rest at 0 V)"
            )
            raise type(exc)(
                f"{exc}; motor stop requested (firmware watchdog: {self.firmware.watchdog_ms} ms), {kept}"
            ) from exc
        self.last_reply = reply
        return reply

    def _on_fault(self, exc: BaseException) -> None:
        self._fault = exc
        self._running = False
        try:
            self._client.emergency_stop()
        except Exception:  # noqa: BLE001 - link gone: the firmware watchdog stops the motor
            pass
        if isinstance(exc, LinkLostError):
            self._client.close()  # the port is gone: the next reset() opens it anew (reconnect)
        self._close_recording()

    def end_episode(self) -> None:
        """End the episode now: motor to 0 V (latched stop until the next reset), recording closed."""
        if self._running:
            self._running = False
            try:
                self._client.emergency_stop(wait=True, attempts=STOP_ATTEMPTS)
                self.stop_acknowledged = True
            except LinkTimeoutError:
                self.stop_acknowledged = False  # the firmware watchdog stops the motor
            except LinkError as exc:
                self.stop_acknowledged = False
                self._on_fault(exc)
        self._close_recording()

    # ------------------------------------------------------------------ recording
    def _record(self, m: dict[str, float], u_cmd: float, omega: np.ndarray) -> None:
        """Record a sample as docs/data_format.md means it: a row's ``u`` is the voltage applied FROM its time
        on (zero-order hold, as the simulator and the identification read it).  A SAMPLE reports the
        state at the end of a period and the voltage applied during it, so each row waits for the
        next reply, which tells the voltage applied after it (the last row: 0 V, the motor stopped)."""
        if self.recorder is None or self.recorder.closed:
            return
        if self._pending is not None:
            self.recorder.write({**self._pending, "u": m["u"], "u_cmd": u_cmd})
        self._pending = {**m, "omega_u_est": omega[0], "omega_l_est": omega[1]}

    def _close_recording(self) -> None:
        """Write the last row (0 V from then on: the episode ended, the motor is stopped) and close."""
        if self.recorder is None:
            return
        if self._pending is not None and not self.recorder.closed and not self.recorder.failed:
            self.recorder.write({**self._pending, "u": 0.0, "u_cmd": 0.0})
        self._pending = None
        self.recorder.close()

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Start an episode: reconnect if needed, bring the rig to rest at 0 V, open a recording.

        Parameters
        ----------
        seed : int, optional
            Seed of the target draw (the rig itself is not random).
        options : dict, optional
            Unused (Gymnasium's signature).

        Returns
        -------
        observation : ndarray
            The first observation (float32).
        info : dict
            The info keys of :class:`drillgym.envs.DrillEnv`.

        Raises
        ------
        SafetyError
            The rig did not come to rest within ``rest_timeout``, or the link failed.
        """
        super().reset(seed=seed)
        self.end_episode()
        self._fault = None
        c = self._client
        if not c.link.is_open:  # after a lost link: reconnect
            self._client = c = RigClient(self.port, self._reply_timeout, self._baudrate)
            self._finalizer.detach()
            self._finalizer = weakref.finalize(self, _stop_motor, c)
        c.strict = False
        try:
            c.identify(self.options.control_dt)
            c.clear_stop()
            c.strict = True
            rest = self._bring_to_rest()
            c.clear_stop()  # idle at 0 V until the first step: the episode starts with the first action
        except LinkError as exc:
            self._on_fault(exc)
            raise
        o = self.options
        self._episode += 1
        self._omega_ref[0], _ = self.task.sample(self.np_random)  # alpha0: the rig's own winding
        m = self.measurements.start(rest)
        # states at rest, angles at the middle of their count: quantizing observation models give the counts back
        self.measurements.fill_state(m, np.zeros(2), np.zeros(2), angle_shift=math.pi / self.firmware.counts_per_rev)
        self.obs_model.reset(_ROW0, self._Y, [self.np_random])
        self._obs[:] = self.obs_model.initial(_ROW0, self._Y, self._omega_ref)
        self.measurements.fill_state(m, np.zeros(2), np.zeros(2))
        self.monitor.reset(_ROW0)
        self.limiter.reset(0.0)
        self._u_prev[0] = 0.0
        self._steps = 0
        meta = {
            "configuration": o.configuration,
            "source": "emulator" if self.firmware.name.startswith("drillgym-emu") else "rig",
            "sample_rate_hz": 1.0 / o.control_dt,
            "description": f"hardware episode {self._episode}",
            "port": self.port,
            "firmware_id": self.firmware.name,
            "protocol_version": P.PROTOCOL_VERSION,
            "counts_per_rev": self.firmware.counts_per_rev,
            "lvdt_m_per_lsb": self.firmware.lvdt_m_per_lsb,
            "lvdt_offset_m": self.measurements.lvdt.offset.tolist(),
            "lvdt_cutoff_hz": self.lvdt_cutoff_hz,
            "omega_ref": float(self._omega_ref[0]),
            "seed": seed,
            "observation": o.observation,
        }
        self.recorder = EpisodeRecorder(
            episode_path(self.record, self._episode), o.lateral, meta, self.flush_interval_s
        )
        self._pending = None
        self._record(m, 0.0, np.zeros(2))
        self._running = True
        self.pacer.next = None  # the first step starts the clock
        return self._obs[0].copy(), self._info(m, np.zeros(2))

    def _bring_to_rest(self) -> list[Reply]:
        """Hold 0 V at the control period until no encoder count changed for ``rest_time``."""
        n_rest = max(2, int(round(self.rest_time / self.options.control_dt)) + 1)
        pacer = Pacer(self.options.control_dt)
        self.limiter.reset(0.0)
        window: list[Reply] = []
        t_end = time.monotonic() + self.rest_timeout
        while True:
            pacer.wait()
            reply = self._exchange(0.0)
            s = reply.sample
            if window and (s.counts_u, s.counts_l) != (window[-1].sample.counts_u, window[-1].sample.counts_l):
                window.clear()
            window.append(reply)
            if len(window) >= n_rest and not s.status & P.Status.STOPPED:
                return window[-n_rest:]
            if time.monotonic() > t_end:
                self._on_fault(SafetyError("rig not at rest"))
                raise SafetyError(
                    f"the rig did not come to rest at 0 V within {self.rest_timeout} s "
                    f"(encoders still moving, or the firmware keeps the motor stopped)"
                )

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        """Send the action's voltage (clamped and slew-limited) and wait for the control period's sample.

        Parameters
        ----------
        action : array_like
            One voltage: / 5 V with ``normalize_action``, else in V.

        Returns
        -------
        observation : ndarray
            The observation at the end of the period (float32).
        reward : float
            The period's reward.
        terminated : bool
            A limit of the task or a safety stop (``info["safety_stop"]``).
        truncated : bool
            The episode reached ``episode_duration``.
        info : dict
            As :class:`drillgym.envs.DrillEnv`, with ``clamped_from`` and ``safety_stop`` when they apply.

        Raises
        ------
        SafetyError
            No episode is running (call :meth:`reset`), or the link failed (:class:`hw.link.LinkError`).
        """
        if not self._running:
            why = f" after a fault ({self._fault})" if self._fault is not None else ""
            raise SafetyError(f"the hardware episode is not running{why}; call reset()")
        requested = action_voltage(action, float(self.action_space.high[0])) * self._scale
        v = min(max(requested, -U_MAX), U_MAX)
        u_cmd, _ = self.limiter.limit(v, self.options.control_dt)  # host safety layer
        tick_error = self.pacer.wait()
        reply = self._exchange(u_cmd)
        if self._steps == 0:  # the episode's clock starts with the first action
            self.measurements.t0_us = reply.sample.timestamp_us - self.firmware.period_us
            self.measurements.t0_host = reply.sent
        m, omega = self.measurements.update(reply)
        o = self.options
        u = np.array([m["u"]])
        self.reward_fn(self._Y, self._MODE, u, self._u_prev, self._omega_ref, self._reward)
        self._u_prev[0] = m["u"]
        self.measurements.observe(self.obs_model, m, self._u_prev, self._omega_ref, self._obs, [self.np_random])
        self.monitor.update(self._Y[:, 3])
        self.task.unsafe(self._Y, self._unsafe)
        self._steps += 1
        try:
            self._record(m, u_cmd, omega)
        except RecordingError as exc:  # an episode never runs unrecorded: stop it, keep what was written
            self._on_fault(exc)
            raise
        stop = None
        if reply.sample.status & P.Status.STOPPED:
            try:
                why = reply.stop if reply.stop is not None else self._client.stop_reason()
            except LinkError:  # the link failed while the motor is stopped anyway: the status bits tell enough
                why = None
            stop = (
                why.name if why is not None else ("WATCHDOG" if reply.sample.status & P.Status.WATCHDOG else "FIRMWARE")
            )
        else:
            reason = (
                check_limits(self.limits, omega[0], omega[1], m["x"], m["y"])
                if o.lateral
                else check_limits(self.limits, omega[0], omega[1])
            )
            stop = reason.name if reason is not None else None
        terminated = bool(self._unsafe[0]) or stop is not None
        truncated = self._steps >= self.task.max_steps
        info = self._info(m, omega, tick_error, reply)
        if v != requested:
            info["clamped_from"] = requested  # V asked for beyond the amplifier range (applied: +-U_MAX)
        if stop is not None:
            info["safety_stop"] = stop
        if terminated:
            info["termination"] = self._termination_reason(stop, m["t"])
        if terminated or truncated:
            self.end_episode()
        return self._obs[0].copy(), float(self._reward[0]), terminated, truncated, info

    def _termination_reason(self, stop: str | None, t: float) -> str:
        """Why the episode was terminated, one line as the simulated envs' ``info["termination"]``: the safety
        stop, or the task's limit with the measured value, the limit and the time (s, the episode's)."""
        if stop is not None:
            return f"safety stop: {stop} at t = {t:.6g} s"
        o, y = self.options, self._Y[0]
        for name, w in (("omega_u", y[2]), ("omega_l", y[3])):
            if abs(w) > o.max_speed:
                return f"over-speed: {name} = {w:.4g} rad/s beyond max_speed = {o.max_speed:g} rad/s at t = {t:.6g} s"
        r = math.hypot(y[4], y[5])
        return (
            f"lateral displacement: r = {r * 1e3:.4g} mm beyond max_lateral = {o.max_lateral * 1e3:g} mm "
            f"at t = {t:.6g} s"
        )

    def _info(
        self, m: dict[str, float], omega: np.ndarray, tick_error: float = 0.0, reply: Reply | None = None
    ) -> dict:
        return {
            "omega_l": float(omega[1]),
            "stuck": bool(self._MODE[0, 1] == 0),
            "friction_torque": math.nan,
            "stick_slip_severity": float(self.monitor.ssi[0]),
            "omega_ref": float(self._omega_ref[0]),
            "voltage": float(m["u"]),
            "time": float(m["t"]),
            "measurement": m,
            "round_trip_s": reply.round_trip if reply is not None else 0.0,
            "tick_error_s": float(tick_error),
            "overruns": self.pacer.overruns,
            "recording": str(self.recording),
        }

    def close(self) -> None:
        """Motor to 0 V, recording closed, port closed (always; safe to call twice)."""
        try:
            self.end_episode()
        finally:
            self._finalizer()
