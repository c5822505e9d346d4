"""One recorded experiment made ready for model comparison.

A recording (:class:`drillgym.io.TimeSeries`, any rate, any length) becomes an
:class:`Experiment`:

* the input ``u`` is kept exactly as recorded (zero-order hold on its own time
  stamps) and later sampled on the simulator's grid;
* the measured channels (``theta_u``, ``theta_l``, fixed-frame ``x``, ``y``) are
  put on a uniform *comparison grid* (default 100 Hz, never above the data's rate);
* speeds the file does not hold are estimated by a Savitzky–Golay derivative
  (scipy) of the recorded angles and LVDT signals; speeds below
  ``stick_threshold`` are set to exactly zero (a stuck disc);
* :meth:`Experiment.initial_states` gives simulator states at any grid index,
  inverting the measurement effects (offsets, skew, ...) of a composition, so
  that a simulation can be (re)started from the data (multiple shooting).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from ..configurations import N_STATE, Configuration, parse_configuration
from ..effects import BASE, Composition
from ..errors import DataFormatError, InputError, InputTypeError
from ..io import TimeSeries
from .reading_noise import angle_noise
from .sensors import invert_measurement

__all__ = ["Experiment", "prepare_experiment", "estimate_rate"]

DEFAULT_COMPARE_RATE_HZ = 100.0
STICK_THRESHOLD = 0.01  # rad/s
SPEED_WINDOW_S = 0.06  # s: Savitzky–Golay window of the speed estimates


def estimate_rate(theta: np.ndarray, fs: float, window_s: float = 0.04, deriv: int = 1) -> np.ndarray:
    """Derivative of a uniformly sampled signal by a cubic Savitzky–Golay filter (robust to encoder quantization).

    Parameters
    ----------
    theta : numpy.ndarray
        The signal.
    fs : float
        Its sample rate (Hz).
    window_s : float, optional
        The filter's window (s).  Default 0.04.
    deriv : int, optional
        The derivative's order.  Default 1.

    Returns
    -------
    numpy.ndarray
        The derivative (units per s^deriv).
    """
    n = len(theta)
    win = max(5, int(round(window_s * fs)) | 1)
    if win > n:
        win = n if n % 2 == 1 else n - 1
    poly = min(3, win - 1)
    if win <= poly:
        return np.gradient(theta, 1.0 / fs) if deriv == 1 else np.gradient(np.gradient(theta, 1.0 / fs), 1.0 / fs)
    return savgol_filter(theta, win, poly, deriv=deriv, delta=1.0 / fs, mode="interp")


@dataclass
class Experiment:
    """A recording on a uniform comparison grid, with estimated speeds.

    Attributes
    ----------
    config : Configuration
        The configuration.
    t : numpy.ndarray
        The comparison grid (s, absolute times of the file).
    fs : float
        Its rate (Hz).
    meas : dict of str to numpy.ndarray
        Measured channels on the grid (``theta_u``, ``theta_l`` in rad; ``x``, ``y`` fixed frame in m, as
        available).
    rates : dict of str to numpy.ndarray
        Their time derivatives (``omega_u``, ``omega_l`` in rad/s; ``Xd``, ``Yd`` in m/s).
    u_time, u_value : numpy.ndarray
        The recorded input (s, V).
    lvdt_lowpass_hz : float or None
        The offline LVDT filter the data went through (applied to the model's lateral outputs as well;
        None: none).
    name : str
        The experiment's name.
    meta : dict
        The recording's metadata.
    speed_noise : dict
        The standard deviation (rad/s) of each speed estimate from encoder quantization.
    recording : TimeSeries or None
        The recording it was prepared from (to compare on another grid, e.g. the recording's own rate).
    t_origin : float or None
        The file time (s) at which the model's clock reads 0 (the run's start, which time-dependent effects
        such as a friction drift count from); None: this experiment's first sample.  A part of a recording
        keeps the whole recording's origin (:attr:`clock_start`).
    """

    config: Configuration
    t: np.ndarray
    fs: float
    meas: dict[str, np.ndarray]
    rates: dict[str, np.ndarray]
    u_time: np.ndarray
    u_value: np.ndarray
    lvdt_lowpass_hz: float | None = 5.0
    name: str = "experiment"
    meta: dict = field(default_factory=dict)
    speed_noise: dict = field(default_factory=dict)
    recording: TimeSeries | None = field(default=None, repr=False, compare=False)
    t_origin: float | None = None

    @property
    def n(self) -> int:
        return len(self.t)

    @property
    def clock_start(self) -> float:
        """The model's clock (s) at this experiment's first sample: 0 for a whole recording, the time since
        the recording's start for a part of it."""
        return 0.0 if self.t_origin is None else float(self.t[0] - self.t_origin)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def input_on_grid(self, dt: float, n_steps: int, t_start: float) -> np.ndarray:
        """The recorded input (zero-order hold on its own samples) averaged over each simulator step.

        Exactly the recorded samples when the grids coincide, and the same impulse per step when the data
        are sampled faster than ``dt``.

        Parameters
        ----------
        dt : float
            The simulator step (s).
        n_steps : int
            Steps.
        t_start : float
            The first step's start (s).

        Returns
        -------
        numpy.ndarray
            The input (V) over [t_start + k dt, t_start + (k + 1) dt), k < n_steps.
        """
        tk, uk = self.u_time, self.u_value
        F = np.concatenate([[0.0], np.cumsum(uk[:-1] * np.diff(tk))])  # integral of the ZOH input at tk

        def integral(tq: np.ndarray) -> np.ndarray:
            out = np.interp(tq, tk, F)
            return np.where(
                tq > tk[-1], F[-1] + (tq - tk[-1]) * uk[-1], np.where(tq < tk[0], (tq - tk[0]) * uk[0], out)
            )

        tq = t_start + np.arange(n_steps + 1) * dt
        return np.diff(integral(tq)) / dt

    def channel(self, name: str) -> np.ndarray:
        """A measured channel, also the derived ``alpha`` = θl − θu and ``r`` = √(x² + y²).

        Parameters
        ----------
        name : str
            The channel.

        Returns
        -------
        numpy.ndarray
            Its samples on the comparison grid.

        Raises
        ------
        InputError
            The recording has no such channel.
        """
        if name == "alpha":
            return self.meas["theta_l"] - self.meas["theta_u"]
        if name == "r":
            return np.hypot(self.meas["x"], self.meas["y"])
        if name not in self.meas:
            raise InputError(f"{self.name}: the recording has no channel {name!r}")
        return self.meas[name]

    def initial_states(self, idx: np.ndarray, P: np.ndarray, composition: Composition | None = None) -> np.ndarray:
        """Mechanical states at grid indices for parameter rows.

        The readings go backwards through the composition's measurement effects (LVDT offsets, skew, any
        user Measurement effect) of each row (:func:`.sensors.invert_measurement`).

        Parameters
        ----------
        idx : numpy.ndarray
            Grid indices.
        P : numpy.ndarray
            Parameter rows (same length), in the layout of ``composition``.
        composition : Composition, optional
            The model (default: the base model).

        Returns
        -------
        numpy.ndarray
            (len(idx), N_STATE) states.
        """
        comp = composition if composition is not None else BASE
        idx = np.asarray(idx, dtype=int)
        P = np.atleast_2d(np.asarray(P, dtype=float))
        n = len(idx)
        zeros = np.zeros(n)
        lateral = self.config.lateral_free and "x" in self.meas
        R = np.column_stack(
            [
                self.meas["theta_u"][idx],
                self.meas.get("theta_l", self.meas["theta_u"])[idx],
                self.meas["x"][idx] if lateral else zeros,
                self.meas["y"][idx] if lateral else zeros,
            ]
        )
        D = np.column_stack(
            [
                self.rates["omega_u"][idx],
                self.rates["omega_l"][idx] if "theta_l" in self.meas else zeros,
                self.rates["Xd"][idx] if lateral else zeros,
                self.rates["Yd"][idx] if lateral else zeros,
            ]
        )
        if comp.has_measurement:
            S, V = np.empty_like(R), np.empty_like(D)
            # once per distinct setting of the measurement's parameters (the fits' other columns vary)
            cols = list(comp.measurement_columns)
            key = P[:, cols] if cols else np.zeros((len(P), 1))
            _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
            for j, i0 in enumerate(first):
                sel = np.flatnonzero(inv.ravel() == j)
                S[sel], V[sel] = invert_measurement(comp, R[sel], D[sel], P[i0])
            R, D = S, V
        Y = np.zeros((n, N_STATE))
        Y[:, 0], Y[:, 1], Y[:, 2], Y[:, 3] = R[:, 0], R[:, 1], D[:, 0], D[:, 1]
        if "theta_l" not in self.meas:
            Y[:, 1], Y[:, 3] = R[:, 0], 0.0
        if self.config is Configuration.FREE_VIBRATION:
            Y[:, 2] = 0.0
        if lateral:
            X, Yf, Xd, Yd = R[:, 2], R[:, 3], D[:, 2], D[:, 3]
            th_u, W = Y[:, 0], Y[:, 2]
            c, s = np.cos(th_u), np.sin(th_u)
            Y[:, 4] = X * c + Yf * s
            Y[:, 5] = -X * s + Yf * c
            a = Xd + Yf * W
            b = Yd - X * W
            Y[:, 6] = c * a + s * b
            Y[:, 7] = -s * a + c * b
        return Y


#: fewest samples a recording must have to be compared
MIN_SAMPLES = 20
#: fewest samples of the comparison grid (one multiple-shooting segment's least)
MIN_GRID_SAMPLES = 10


def prepare_experiment(
    ts: TimeSeries,
    config: str | Configuration | None = None,
    *,
    compare_rate_hz: float = DEFAULT_COMPARE_RATE_HZ,
    lvdt_lowpass_hz: float | None = 5.0,
    stick_threshold: float = STICK_THRESHOLD,
    name: str | None = None,
) -> Experiment:
    """Make a validated recording ready for comparison (see the module docstring).

    Parameters
    ----------
    ts : TimeSeries
        The recording.
    config : str or Configuration, optional
        The configuration when the recording has none (another than the recording's is refused).
    compare_rate_hz : float, optional
        Comparison grid rate (Hz).
    lvdt_lowpass_hz : float or None, optional
        The LVDTs' low-pass cut-off (Hz).  Default 5.
    stick_threshold : float, optional
        Speed (rad/s) below which a disc counts as stuck.
    name : str, optional
        The experiment's name (default: the recording's source).

    Returns
    -------
    Experiment
        The experiment.

    Raises
    ------
    InputError
        An unknown or missing configuration, or one that contradicts the recording's (the message names
        the file).
    DataFormatError
        Too few samples.
    """
    if isinstance(compare_rate_hz, bool) or not isinstance(compare_rate_hz, numbers.Real):
        raise InputTypeError(f"the comparison rate (--rate) must be a number of Hz, got {compare_rate_hz!r}")
    if not (math.isfinite(compare_rate_hz) and compare_rate_hz > 0):
        raise InputError(f"the comparison rate (--rate) must be a positive number of Hz, got {compare_rate_hz!r}")
    cfg = parse_configuration(config) if config is not None else ts.configuration
    if ts.configuration is not None and cfg is not ts.configuration:
        raise InputError(
            f"{ts.source}: the recording is of configuration {ts.configuration.label}, but {cfg.label} was "
            f"requested (config); a recording is compared with the model of its own configuration"
        )
    if cfg is None:
        raise InputError(f"{ts.source}: no configuration in the file's metadata; pass one (--config)")
    ts.validate(cfg)
    fs_data = ts.sample_rate_hz
    if len(ts) < MIN_SAMPLES:
        raise DataFormatError(f"{ts.source}: {len(ts)} samples are too few to compare (need >= {MIN_SAMPLES})")
    if compare_rate_hz > fs_data * 1.01:  # 1 %: a jittered clock's median rate; the grid is capped at it anyway
        raise InputError(
            f"the comparison rate (--rate) {compare_rate_hz:g} Hz is above the recording's sample rate "
            f"{fs_data:.6g} Hz ({ts.source}); choose <= {fs_data:.6g}"
        )
    # uniform grid at the data rate (capped at 2 kHz) for derivatives
    fs_w = min(fs_data, 2000.0)
    uni = ts.resample(fs_w)
    rates: dict[str, np.ndarray] = {}
    cols = uni.columns
    speed_noise: dict[str, float] = {}
    for ang, om in (("theta_u", "omega_u"), ("theta_l", "omega_l")):
        if ang not in cols:
            continue
        w = cols[om] if om in cols else estimate_rate(cols[ang], fs_w, window_s=SPEED_WINDOW_S)
        speed_noise[om] = 0.005 if om in cols else _derivative_noise(cols[ang], fs_w)
        w = np.where(np.abs(w) < stick_threshold, 0.0, w)
        rates[om] = w
    if "x" in cols and "y" in cols:
        rates["Xd"] = estimate_rate(cols["x"], fs_w, window_s=0.1)
        rates["Yd"] = estimate_rate(cols["y"], fs_w, window_s=0.1)
    fs_c = min(float(compare_rate_hz), fs_w)
    n_c = int(math.floor(ts.duration * fs_c + 1e-9)) + 1
    if n_c < MIN_GRID_SAMPLES:
        raise InputError(
            f"the comparison rate (--rate) {compare_rate_hz:g} Hz gives {n_c} samples over the recording's "
            f"{ts.duration:g} s ({ts.source}); need >= {MIN_GRID_SAMPLES}: choose >= "
            f"{(MIN_GRID_SAMPLES - 1) / ts.duration:.3g} Hz"
        )
    t_c = uni.t[0] + np.arange(n_c) / fs_c
    meas = {c: np.interp(t_c, uni.t, cols[c]) for c in ("theta_u", "theta_l", "x", "y") if c in cols}
    rates = {k: np.interp(t_c, uni.t, v) for k, v in rates.items()}
    for k in ("omega_u", "omega_l"):
        if k in rates:
            rates[k] = np.where(np.abs(rates[k]) < stick_threshold, 0.0, rates[k])
    if cfg is Configuration.UPPER:
        meas.pop("theta_l", None)
    if not cfg.lateral_free:
        meas.pop("x", None)
        meas.pop("y", None)
    return Experiment(
        cfg,
        t_c,
        fs_c,
        meas,
        rates,
        ts.t.copy(),
        ts.u.copy(),
        lvdt_lowpass_hz,
        name or str(ts.source),
        dict(ts.meta),
        speed_noise,
        ts,
    )


def _derivative_noise(theta: np.ndarray, fs: float) -> float:
    """Standard deviation (rad/s) of the Savitzky–Golay speed estimate caused by the reading's noise
    (:func:`.reading_noise.angle_noise`: one count / √12, or the scatter of a reading off any lattice of counts;
    1e-4 rad / √12 for an angle that never changes)."""
    noise = angle_noise(theta)
    win = max(5, int(round(SPEED_WINDOW_S * fs)) | 1)
    c = savgol_coeffs(win, min(3, win - 1), deriv=1, delta=1.0 / fs)
    return (noise if noise is not None else 1e-4 / np.sqrt(12.0)) * float(np.linalg.norm(c))
