"""Observation models: (state or sensor readings, voltage, target) -> observation vector.

Three modes, each a class with a documented layout (``names``), a Box
(``space``) and batched ``observe`` (rows = rigs).  Lateral entries exist only
in the 'lateral' and 'coupled' configurations.  Units: rad, rad/s, mm, mm/s, V.

``full`` (:class:`FullObservation`, the true state)::

    omega_u, omega_l, alpha, [X, Y, dX/dt, dY/dt,] u_prev, omega_ref

``sensors`` (:class:`SensorObservation`, what the rig measures)::

    theta_u_wrapped, theta_l_wrapped, alpha_meas, omega_u_est, omega_l_est, [X_meas, Y_meas,] u_prev, omega_ref

    theta_*_wrapped: quantized encoder angle wrapped to [-pi, pi); alpha_meas = theta_l_q - theta_u_q;
    omega_*_est: backward difference of the quantized angles over the control period, first-order
    low-pass (``velocity_filter_tau``); X_meas, Y_meas: LVDT readings (noise).  The channels pass
    through the composition's Measurement effects first (offset, skew, ... any user effect).

``motor`` (:class:`MotorObservation`, only the motor-side encoder: the field case)::

    omega_u_inc[0..H-1], u_hist[0..H-1], omega_ref

    omega_u_inc[i]: quantized theta_u increment over the control period i periods ago / control_dt
    (raw, unfiltered; i = 0 newest); u_hist[i]: voltage applied over that period.

``u_prev`` is the (clipped) voltage applied over the last control period, ``omega_ref``
the episode's target speed of the lower disc.  Values are clipped into the Box.  The reset
observation has zero speed estimates and noise-free LVDT readings of the rest position.

The sensor side is reusable by the hardware environment: :class:`SensorObservation` and
:class:`MotorObservation` build the vector from readings (``from_readings``); the
simulated readings come from :class:`SimulatedSensors` (the composition's Measurement effects,
then the encoders and LVDTs of :mod:`drillgym.measurement`).  Per control period, both modes are
one compiled call (:mod:`.sensor_kernel`, specialised per composition, with
:mod:`.observation_kernels`: readings, speed estimators, assembly and clipping of all rigs).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium import spaces
from numba import njit

from ..effects.composition import BASE, Composition
from ..errors import InputError
from ..measurement import EncoderVelocityEstimator, lvdt_measure, quantize_angle
from . import observation_kernels as ok
from .observation_kernels import MM, rotate, rotate_compiled
from .options import U_MAX, EnvOptions

__all__ = [
    "ObservationModel",
    "FullObservation",
    "SensorObservation",
    "MotorObservation",
    "SimulatedSensors",
    "make_observation_model",
    "fixed_frame_lateral",
    "full_obs_row",
]

ALPHA_BOUND = 50.0  # rad


def fixed_frame_lateral(Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(X, Y) of the lower disc centre in the fixed (LVDT) frame (m) from states (n, n_state)."""
    return rotate(Y[:, 4], Y[:, 5], np.cos(Y[:, 0]), np.sin(Y[:, 0]))


@njit(cache=True)
def full_obs_row(y, u_prev, omega_ref, lateral, low, high, out):
    """The 'full' observation of one state ``y`` into ``out`` (compiled; used inside the engine's kernel)."""
    out[0] = y[2]
    out[1] = y[3]
    out[2] = y[1] - y[0]
    j = 3
    if lateral:
        c = np.cos(y[0])
        s = np.sin(y[0])
        w = y[2]
        vx = y[6] - w * y[5]  # velocity of B, rotating-frame components
        vy = y[7] + w * y[4]
        X, Yf = rotate_compiled(y[4], y[5], c, s)
        dX, dY = rotate_compiled(vx, vy, c, s)
        out[3] = MM * X
        out[4] = MM * Yf
        out[5] = MM * dX
        out[6] = MM * dY
        j = 7
    out[j] = u_prev
    out[j + 1] = omega_ref
    for i in range(out.shape[0]):
        out[i] = min(max(out[i], low[i]), high[i])


@njit(cache=True)
def _observe_full(Y, u_prev, omega_ref, lateral, low, high, out):
    for k in range(Y.shape[0]):
        full_obs_row(Y[k], u_prev[k], omega_ref[k], lateral, low, high, out[k])


class ObservationModel:
    """Base class: layout ``names``, bounds, ``space``; batched ``reset`` and ``observe``.

    Parameters
    ----------
    n : int
        Number of rigs.
    options : EnvOptions
        The environment's options (mode, limits, sensors, effects).

    Attributes
    ----------
    names : tuple of str
        Layout of an observation row.
    space : gymnasium.spaces.Box
        The observation space of one rig (float32).
    """

    mode: str = ""
    #: True when the engine's compiled kernel writes this observation itself (``full_obs_row``)
    compiled: bool = False

    def __init__(self, n: int, options: EnvOptions) -> None:
        self.n = n
        self.options = options
        self.lateral = options.lateral
        names, low, high = self._layout(options)
        self.names: tuple[str, ...] = tuple(names)
        self.low = np.asarray(low, dtype=np.float32)
        self.high = np.asarray(high, dtype=np.float32)
        self.space = spaces.Box(self.low, self.high, dtype=np.float32)

    @property
    def dim(self) -> int:
        """Length of an observation row."""
        return len(self.names)

    def _layout(self, o: EnvOptions) -> tuple[list[str], list[float], list[float]]:  # pragma: no cover
        raise NotImplementedError

    def _check_out(self, out: np.ndarray) -> int:
        """Number of rigs; ``out`` must be the (n, dim) float32 observation array."""
        if out.shape != (self.n, self.dim) or out.dtype != np.float32:
            raise ValueError(
                f"out must be a float32 array of shape ({self.n}, {self.dim}), got {out.dtype} {out.shape}"
            )
        return self.n

    @staticmethod
    def _tail(o: EnvOptions) -> tuple[list[str], list[float], list[float]]:
        return ["u_prev", "omega_ref"], [-U_MAX, 0.0], [U_MAX, o.max_speed]

    def reset(self, index: np.ndarray, Y: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """Start the rigs ``index`` (states ``Y[index]`` at rest) with fresh estimator states."""

    def initial(self, index: np.ndarray, Y: np.ndarray, omega_ref: np.ndarray) -> np.ndarray:
        """Observations (len(index), dim) of rigs ``index`` just after reset (at rest, u_prev = 0)."""
        raise NotImplementedError

    def observe(
        self,
        Y: np.ndarray,
        u_prev: np.ndarray,
        omega_ref: np.ndarray,
        out: np.ndarray,
        rngs: Sequence[np.random.Generator],
        skip: np.ndarray | None = None,
    ) -> None:
        """Write the observations of all rigs into ``out`` (n, dim) float32 after one control period.

        ``Y`` true states (n, n_state), ``u_prev`` voltage applied over the period (V), ``omega_ref``
        targets (rad/s); ``rngs`` one generator per rig (sensor noise); rigs flagged in ``skip``
        are about to be reset and draw no random numbers."""
        raise NotImplementedError


class FullObservation(ObservationModel):
    """The true state (see the module docstring for the layout).

    Parameters
    ----------
    n : int
        Number of rigs.
    options : EnvOptions
        The environment's options.
    """

    mode = "full"
    compiled = True

    def _layout(self, o: EnvOptions):
        w = 2.0 * o.max_speed
        names, low, high = ["omega_u", "omega_l", "alpha"], [-w, -w, -ALPHA_BOUND], [w, w, ALPHA_BOUND]
        if o.lateral:
            d = 2.0 * o.max_lateral * MM
            v = 2.0 * d * o.max_speed
            names += ["X", "Y", "dX", "dY"]
            low += [-d, -d, -v, -v]
            high += [d, d, v, v]
        tn, tl, th = self._tail(o)
        return names + tn, low + tl, high + th

    def initial(self, index, Y, omega_ref) -> np.ndarray:
        out = np.empty((len(index), self.dim), dtype=np.float32)
        _observe_full(Y[index], np.zeros(len(index)), omega_ref[index], self.lateral, self.low, self.high, out)
        return out

    def observe(self, Y, u_prev, omega_ref, out, rngs, skip=None) -> None:
        _observe_full(Y, u_prev, omega_ref, self.lateral, self.low, self.high, out)


class SimulatedSensors:
    """The rig's sensors on simulated states: the composition's Measurement effects (offsets, skew,
    gains, ... of :mod:`drillgym.effects`), quantized encoders on both discs, LVDTs with white noise
    ``lvdt_noise_std`` (m).

    ``composition`` is the rigs' model and ``P`` its (n, n_params) parameter matrix, read live (the
    environments pass the simulator's own matrix, so a domain-randomised measurement parameter
    acts in the episode that drew it).  The compiled readings are the client template
    :mod:`.sensor_kernel` of the composition, loaded on first use.

    Noise is drawn per rig from that rig's generator in blocks of ``block`` periods, so a rig's
    readings depend only on its own seed (a vector env reproduces single envs exactly).
    ``noise`` (n, block, 2) standard normal draws (an empty array without noise), ``pos`` (n,)
    the next unused period of each rig's block: the compiled observation kernels read and
    advance them, :meth:`refill_spent` draws the next blocks."""

    def __init__(
        self,
        n: int,
        counts_per_rev: int,
        lvdt_noise_std: float,
        lateral: bool,
        composition: Composition = BASE,
        P: np.ndarray | None = None,
        block: int = 128,
    ) -> None:
        self.n, self.cpr, self.noise_std, self.lateral = n, counts_per_rev, lvdt_noise_std, lateral
        self.composition = composition
        self.P = composition.matrix(None, n) if P is None else P
        if self.P.shape != (n, composition.n_params):
            raise ValueError(
                f"parameter matrix must have shape ({n}, {composition.n_params}) for the model "
                f"{composition.label!r}, got {self.P.shape}"
            )
        self.block = block
        self.noisy = lateral and lvdt_noise_std > 0
        self.noise = np.zeros((n, block, 2)) if self.noisy else np.zeros((0, 1, 2))
        self.pos = np.zeros(n, dtype=np.int64)

    @property
    def kernel(self):
        """The composition's compiled sensor module (:mod:`.sensor_kernel`; the composition caches it, and
        the sensors keep no module of their own, so they pickle)."""
        return self.composition.kernels.client("drillgym.envs.sensor_kernel")

    def reset(self, index: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        if self.noisy:
            for i in index:
                self._refill(i, rngs[i])

    def _refill(self, i: int, rng: np.random.Generator) -> None:
        rng.standard_normal(out=self.noise[i])
        self.pos[i] = 0

    def refill_spent(self, rngs: Sequence[np.random.Generator], skip: np.ndarray | None = None) -> None:
        """Draw a new noise block for every rig whose block is used up, except rigs flagged in
        ``skip`` (about to be reset, which draws their block): those restart their old block."""
        full = self.pos >= self.block
        for i in np.flatnonzero(full if skip is None else full & ~skip):
            self._refill(i, rngs[i])
        self.pos[full] = 0

    def constants(self, lateral: bool, a: float, dt: float, low: np.ndarray, high: np.ndarray) -> np.ndarray:
        """The constants of the compiled 'sensors' kernels (encoders, LVDT noise, filter ``a``, period
        ``dt`` (s), bounds); ``lateral``: the observation has LVDT entries."""
        return ok.sensor_constants(lateral, self.cpr, a, dt, self.noise_std if self.noisy else 0.0, low, high)

    def channels(self, Y: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """(4, m) channels theta_u, theta_l (rad), X, Y (m) of the states ``Y`` (m, n_state) of rigs
        ``index`` (default all) as read before quantization and noise (Measurement effects applied)."""
        P = self.P if index is None else self.P[index]
        return self.kernel.measured_channels_batch(np.ascontiguousarray(Y, dtype=np.float64), np.ascontiguousarray(P))

    def encoders(self, Y: np.ndarray, index: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Quantized (theta_u, theta_l) in rad of the states ``Y`` of rigs ``index`` (default all)."""
        c = self.channels(Y, index)
        return quantize_angle(c[0], self.cpr), quantize_angle(c[1], self.cpr)

    def lvdts(
        self, Y: np.ndarray, rngs: Sequence[np.random.Generator], skip: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """LVDT readings (X_meas, Y_meas) in m of all rigs (advances the noise blocks as the kernels do)."""
        c = self.channels(Y)
        xm, ym = lvdt_measure(c[2], c[3])
        if self.noisy:
            e = self.noise[np.arange(len(self.pos)), self.pos]
            xm += self.noise_std * e[:, 0]
            ym += self.noise_std * e[:, 1]
            self.pos += 1
            self.refill_spent(rngs, skip)
        return xm, ym


class SensorObservation(ObservationModel):
    """Encoder angles, estimated speeds, LVDT readings (see the module docstring for the layout).

    ``est_u``, ``est_l``: the speed estimators of the two encoders; their ``prev`` / ``omega``
    arrays are rows of the state ``E`` (4, n) that the compiled kernels update.

    Parameters
    ----------
    n : int
        Number of rigs.
    options : EnvOptions
        The environment's options (mode, limits, sensors, effects).
    sensors : SimulatedSensors, optional
        The simulated sensors; default built from ``options``.
    params : ndarray, optional
        The rigs' (n, n_params) parameter matrix, read live by the simulated sensors; default the
        options' parameters.
    """

    mode = "sensors"

    def __init__(
        self, n: int, options: EnvOptions, sensors: SimulatedSensors | None = None, params: np.ndarray | None = None
    ) -> None:
        super().__init__(n, options)
        o = options
        self.sensors = sensors or SimulatedSensors(
            n, o.counts_per_rev, o.lvdt_noise_std, o.lateral, o.effects, _params(n, o, params)
        )
        self._observe_fn = None
        self.est_u = EncoderVelocityEstimator(n, o.control_dt, o.velocity_filter_tau)
        self.est_l = EncoderVelocityEstimator(n, o.control_dt, o.velocity_filter_tau)
        self.E = np.zeros((4, n))
        self.est_u.prev, self.est_u.omega, self.est_l.prev, self.est_l.omega = self.E
        self.cv = self.sensors.constants(self.lateral, self.est_u.a, self.est_u.dt, self.low, self.high)

    def _layout(self, o: EnvOptions):
        w = 2.0 * o.max_speed
        names = ["theta_u_wrapped", "theta_l_wrapped", "alpha_meas", "omega_u_est", "omega_l_est"]
        low, high = [-np.pi, -np.pi, -ALPHA_BOUND, -w, -w], [np.pi, np.pi, ALPHA_BOUND, w, w]
        if o.lateral:
            d = 2.0 * o.max_lateral * MM
            names += ["X_meas", "Y_meas"]
            low += [-d, -d]
            high += [d, d]
        tn, tl, th = self._tail(o)
        return names + tn, low + tl, high + th

    def reset(self, index, Y, rngs) -> None:
        tu, tl = self.sensors.encoders(Y[index], index)
        self.est_u.reset(tu, index)
        self.est_l.reset(tl, index)
        self.sensors.reset(index, rngs)

    def observe(self, Y, u_prev, omega_ref, out, rngs, skip=None) -> None:
        s = self.sensors
        fn = self._observe_fn or self._bind()
        if fn(Y, s.P, u_prev, omega_ref, self.E, s.noise, s.pos, self.cv, out):
            s.refill_spent(rngs, skip)

    def _bind(self):
        self._observe_fn = self.sensors.kernel.sensors_observe
        return self._observe_fn

    def initial(self, index, Y, omega_ref) -> np.ndarray:
        c = self.sensors.channels(Y[index], index)
        tu, tl = quantize_angle(c[0], self.sensors.cpr), quantize_angle(c[1], self.sensors.cpr)
        xm, ym = lvdt_measure(c[2], c[3]) if self.lateral else (tu, tl)  # noise-free at rest
        out = np.empty((len(index), self.dim), dtype=np.float32)
        zero = np.zeros(len(index))
        ok.sensors_rows(tu, tl, xm, ym, zero, omega_ref[index], self.E, self.cv, False, out)
        return out

    def from_readings(
        self,
        theta_u: np.ndarray,
        theta_l: np.ndarray,
        X: np.ndarray | None,
        Y: np.ndarray | None,
        u_prev: np.ndarray,
        omega_ref: np.ndarray,
        out: np.ndarray,
    ) -> None:
        """Observation from one period's readings; updates the speed estimators (call once per period).

        Parameters
        ----------
        theta_u, theta_l : ndarray
            Encoder angles (rad), one per rig.
        X, Y : ndarray or None
            LVDT readings (m); None or ignored without lateral entries.
        u_prev : ndarray
            Voltage applied over the period (V).
        omega_ref : ndarray
            Target speeds (rad/s).
        out : ndarray
            The (n, dim) float32 observation array, written in place.
        """
        n = self._check_out(out)
        theta_u, theta_l = _rows(theta_u, n, "theta_u"), _rows(theta_l, n, "theta_l")
        if self.lateral:
            X, Y = _rows(X, n, "X"), _rows(Y, n, "Y")
        else:
            X, Y = theta_u, theta_l
        ok.sensors_rows(
            theta_u,
            theta_l,
            X,
            Y,
            _rows(u_prev, n, "u_prev"),
            _rows(omega_ref, n, "omega_ref"),
            self.E,
            self.cv,
            True,
            out,
        )


class MotorObservation(ObservationModel):
    """Motor-side encoder increments and voltage history (see the module docstring for the layout).

    ``est``: the raw increment estimator (its ``prev`` / ``omega`` are rows of ``E`` (2, n));
    ``hist`` (n, 2H): increments (rad/s) then voltages (V), newest first.

    Parameters
    ----------
    n : int
        Number of rigs.
    options : EnvOptions
        The environment's options (mode, limits, sensors, effects).
    sensors : SimulatedSensors, optional
        The simulated sensors; default built from ``options``.
    params : ndarray, optional
        The rigs' (n, n_params) parameter matrix, read live by the simulated sensors; default the
        options' parameters.
    """

    mode = "motor"

    def __init__(
        self, n: int, options: EnvOptions, sensors: SimulatedSensors | None = None, params: np.ndarray | None = None
    ) -> None:
        super().__init__(n, options)
        o = options
        self.H = o.motor_history
        self.sensors = sensors or SimulatedSensors(n, o.counts_per_rev, 0.0, False, o.effects, _params(n, o, params))
        self._observe_fn = None
        self.est = EncoderVelocityEstimator(n, o.control_dt, 0.0)  # raw increments / control_dt
        self.E = np.zeros((2, n))
        self.est.prev, self.est.omega = self.E
        self.hist = np.zeros((n, 2 * self.H))
        self.cv = ok.motor_constants(self.sensors.cpr, self.est.a, self.est.dt, self.low, self.high)

    def _layout(self, o: EnvOptions):
        H, w = o.motor_history, 2.0 * o.max_speed
        names = [f"omega_u_inc_{i}" for i in range(H)] + [f"u_hist_{i}" for i in range(H)] + ["omega_ref"]
        return names, [-w] * H + [-U_MAX] * H + [0.0], [w] * H + [U_MAX] * H + [o.max_speed]

    def reset(self, index, Y, rngs) -> None:
        tu, _ = self.sensors.encoders(Y[index], index)
        self.est.reset(tu, index)
        self.hist[index] = 0.0

    def initial(self, index, Y, omega_ref) -> np.ndarray:
        out = np.empty((len(index), self.dim), dtype=np.float32)
        ref = omega_ref[index]
        ok.motor_rows(ref, ref, ref, self.E, self.hist, self.cv, False, out)  # empty history: angles unused
        return out

    def observe(self, Y, u_prev, omega_ref, out, rngs, skip=None) -> None:
        fn = self._observe_fn
        if fn is None:
            fn = self._observe_fn = self.sensors.kernel.motor_observe
        fn(Y, self.sensors.P, u_prev, omega_ref, self.E, self.hist, self.cv, out)

    def from_readings(self, theta_u: np.ndarray, u_prev: np.ndarray, omega_ref: np.ndarray, out: np.ndarray) -> None:
        """Observation from one period's motor encoder reading (call once per control period).

        Parameters
        ----------
        theta_u : ndarray
            Motor encoder angle (rad), one per rig.
        u_prev : ndarray
            Voltage applied over the period (V).
        omega_ref : ndarray
            Target speeds (rad/s).
        out : ndarray
            The (n, dim) float32 observation array, written in place.
        """
        n = self._check_out(out)
        ok.motor_rows(
            _rows(theta_u, n, "theta_u"),
            _rows(u_prev, n, "u_prev"),
            _rows(omega_ref, n, "omega_ref"),
            self.E,
            self.hist,
            self.cv,
            True,
            out,
        )


def _rows(x, n: int, name: str) -> np.ndarray:
    """``x`` as n float64 values, one per rig (a scalar or a single value is broadcast)."""
    a = np.asarray(x, dtype=np.float64)
    if a.shape == (n,):
        return a
    if a.size == n:
        return np.ascontiguousarray(a.reshape(n))
    if a.size == 1:
        return np.full(n, a.reshape(()))
    raise InputError(f"{name} must hold one value per rig ({n}), got shape {a.shape}")


_MODELS = {"full": FullObservation, "sensors": SensorObservation, "motor": MotorObservation}


def _params(n: int, o: EnvOptions, params: np.ndarray | None) -> np.ndarray:
    """The rigs' (n, n_params) parameter matrix: ``params`` (live, e.g. the simulator's) or the options'."""
    if params is not None:
        return params
    return o.effects.matrix(o.rig_params, n, o.effect_params)


def make_observation_model(n: int, options: EnvOptions, params: np.ndarray | None = None) -> ObservationModel:
    """The observation model of ``options.observation`` for n rigs.

    Parameters
    ----------
    n : int
        Number of rigs.
    options : EnvOptions
        The environment's options.
    params : ndarray, optional
        The rigs' (n, n_params) parameter matrix in the layout of ``options.effects``, read live by the
        simulated sensors; default the options' parameters and effect values.

    Returns
    -------
    ObservationModel
        A :class:`FullObservation`, :class:`SensorObservation` or :class:`MotorObservation`.
    """
    if options.observation == "full":
        return FullObservation(n, options)
    return _MODELS[options.observation](n, options, params=params)
