"""The rig's measurement chain: encoders, LVDTs and the report's offline processing.

* Encoders on both discs: ``counts_per_rev`` (default 8000: 2000 lines, 4x
  decoding).  The angle is known to one count: ``quantize_angle``.
* LVDTs on the lateral constraints, fixed frame, noise of a few micrometres.
* Measurement effects of a composition (e.g. the library's ``lvdt_offset``,
  ``lvdt_skew``; :mod:`drillgym.effects`) act on the channels before quantisation
  and noise, never in the dynamics (``measure_trajectory``).
* Offline, the report low-passed the LVDT signals at 5 Hz, zero phase
  (``lowpass_zero_phase``); online (environments, hardware) a causal filter.
* Speeds are not measured: ``EncoderVelocityEstimator`` differentiates the
  quantized angles and low-passes them (first order), causally.

``measure_trajectory`` turns a simulated run into a synthetic measurement in
the interchange format (the tests' "measurements with a hidden effect").
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import signal

__all__ = [
    "DEFAULT_COUNTS_PER_REV",
    "DEFAULT_LVDT_NOISE",
    "quantize_angle",
    "angle_to_counts",
    "counts_to_angle",
    "lvdt_measure",
    "lowpass_zero_phase",
    "EncoderVelocityEstimator",
    "MeasurementModel",
    "measure_trajectory",
    "encoder_reading",
    "lvdt_reading",
    "filtered_speed",
]

DEFAULT_COUNTS_PER_REV = 8000
DEFAULT_LVDT_NOISE = 3e-6  # m (standard deviation)
TWO_PI = 2.0 * np.pi


def angle_to_counts(theta: np.ndarray | float, counts_per_rev: int = DEFAULT_COUNTS_PER_REV) -> np.ndarray:
    """Encoder counts (integers) for an angle (rad); floor as an incremental encoder counts."""
    return np.floor(np.asarray(theta, dtype=float) * (counts_per_rev / TWO_PI)).astype(np.int64)


def counts_to_angle(counts: np.ndarray | int, counts_per_rev: int = DEFAULT_COUNTS_PER_REV) -> np.ndarray:
    """Angle (rad) of encoder counts."""
    return np.asarray(counts, dtype=float) * (TWO_PI / counts_per_rev)


# --- elementwise formulas ------------------------------------------------------------------
# Each takes numpy arrays or floats and calls nothing but numpy ufuncs, so numba compiles the
# very same function into the environments' observation kernel (drillgym.envs.observation_kernels):
# one formula per quantity for the numpy and the compiled path.


def encoder_reading(theta, counts_per_rev):
    """The angle (rad) an encoder with ``counts_per_rev`` (> 0: quantized; <= 0: exact) reports for
    ``theta`` (rad): the whole counts below theta (floor, as an incremental encoder counts), in rad.

    Equal to ``counts_to_angle(angle_to_counts(theta))``; ``+ 0.0`` turns -0.0 into 0.0 as the
    integer counts do."""
    if counts_per_rev <= 0:
        return theta
    return np.floor(theta * (counts_per_rev / TWO_PI)) * (TWO_PI / counts_per_rev) + 0.0


def lvdt_reading(X, Y, x0, y0, cos_skew, sin_skew):
    """Noise-free LVDT readings (m) of the fixed-frame displacement (X, Y) (m): offsets ``x0``, ``y0``
    (m) and the y axis rotated by ``skew`` from perpendicular (its cosine and sine)."""
    return X + x0, Y * cos_skew + X * sin_skew + y0


def filtered_speed(omega, theta, theta_prev, a, dt):
    """One period of the encoder speed estimate (rad/s): the backward difference of the angles
    ``theta_prev`` -> ``theta`` (rad) over ``dt`` (s), low-passed with the first-order filter
    coefficient ``a`` = exp(-dt / tau) (0: raw difference) from the previous estimate ``omega``."""
    return a * omega + (1.0 - a) * ((theta - theta_prev) / dt)


def quantize_angle(theta: np.ndarray | float, counts_per_rev: int = DEFAULT_COUNTS_PER_REV) -> np.ndarray:
    """The angle an encoder with ``counts_per_rev`` reports (rad)."""
    return encoder_reading(np.asarray(theta, dtype=float), counts_per_rev)


def lvdt_measure(
    X: np.ndarray, Y: np.ndarray, noise_std: float = 0.0, rng: np.random.Generator | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """LVDT readings (m) of the fixed-frame displacement (X, Y) (m) with white noise of ``noise_std`` (m)."""
    xm = np.array(X, dtype=float)
    ym = np.array(Y, dtype=float)
    if noise_std > 0:
        rng = rng or np.random.default_rng()
        xm = xm + rng.normal(0.0, noise_std, xm.shape)
        ym = ym + rng.normal(0.0, noise_std, ym.shape)
    return xm, ym


def lowpass_zero_phase(x: np.ndarray, fs_hz: float, cutoff_hz: float = 5.0, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (the report's offline LVDT processing), along the last axis.

    ``scipy.signal.sosfiltfilt`` with its defaults (odd extension of 3 (2 n_sections + 1) samples, each pass
    started in the steady state of the first sample), sample for sample: for 2-D float arrays its arithmetic
    in one compiled loop without the GIL (the segmented fits filter every prediction: on 272 segments of 201
    samples 0.59 ms against scipy's 0.87 ms, and the other threads run meanwhile); other shapes in scipy
    itself."""
    xa = np.asarray(x, dtype=float)
    if cutoff_hz >= fs_hz / 2:
        return xa
    sos, zi, pad = _butter_sos(order, float(cutoff_hz), float(fs_hz))
    if xa.ndim != 2 or xa.shape[1] <= pad:
        return signal.sosfiltfilt(sos, xa, axis=-1)
    return _sosfiltfilt_rows(sos, zi, np.ascontiguousarray(xa), pad)


@functools.lru_cache(maxsize=64)
def _butter_sos(order: int, cutoff_hz: float, fs_hz: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Second-order sections of the Butterworth low-pass, their steady-state initial conditions per unit
    input (``sosfilt_zi``) and ``sosfiltfilt``'s default padding (samples), designed once per setting (the fits
    filter every prediction); only read."""
    sos = signal.butter(order, cutoff_hz, fs=fs_hz, output="sos")
    ntaps = 2 * sos.shape[0] + 1 - min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0)))
    return sos, signal.sosfilt_zi(sos), 3 * ntaps


@njit(cache=True, nogil=True)
def _sosfilt_pass(sos: np.ndarray, zi: np.ndarray, x: np.ndarray, y: np.ndarray, reverse: bool) -> None:
    """One pass of the cascade over x into y (reversed order if ``reverse``), from the steady state of its
    first sample: scipy's ``_sosfilt`` loop (transposed direct form II), operation for operation."""
    n = x.shape[0]
    ns = sos.shape[0]
    z = np.empty((ns, 2))
    x0 = x[n - 1] if reverse else x[0]
    for s in range(ns):
        z[s, 0] = zi[s, 0] * x0
        z[s, 1] = zi[s, 1] * x0
    for i in range(n):
        j = n - 1 - i if reverse else i
        x_cur = x[j]
        for s in range(ns):
            x_new = sos[s, 0] * x_cur + z[s, 0]
            z[s, 0] = sos[s, 1] * x_cur - sos[s, 4] * x_new + z[s, 1]
            z[s, 1] = sos[s, 2] * x_cur - sos[s, 5] * x_new
            x_cur = x_new
        y[i] = x_cur


@njit(cache=True, nogil=True)
def _sosfiltfilt_rows(sos: np.ndarray, zi: np.ndarray, X: np.ndarray, pad: int) -> np.ndarray:
    """``sosfiltfilt`` of each row of X (odd extension by ``pad`` samples)."""
    B, n = X.shape
    out = np.empty((B, n))
    m = n + 2 * pad
    ext = np.empty(m)
    fwd = np.empty(m)
    back = np.empty(m)
    for b in range(B):
        row = X[b]
        for i in range(pad):
            ext[i] = 2 * row[0] - row[pad - i]
            ext[pad + n + i] = 2 * row[n - 1] - row[n - 2 - i]
        for i in range(n):
            ext[pad + i] = row[i]
        _sosfilt_pass(sos, zi, ext, fwd, False)
        _sosfilt_pass(sos, zi, fwd, back, True)  # back[i] is the filtered sample m - 1 - i
        for i in range(n):
            out[b, i] = back[m - 1 - pad - i]
    return out


class EncoderVelocityEstimator:
    """Causal speed estimate from quantized angles: backward difference, then a first-order low-pass.

    Vectorised over a batch: angles of shape (n,).

    Parameters
    ----------
    n : int
        Number of rigs.
    dt : float
        Sample period (s).
    tau : float, optional
        Time constant of the low-pass (s; 0: raw difference).  Default 0.02.
    """

    def __init__(self, n: int, dt: float, tau: float = 0.02) -> None:
        self.dt = float(dt)
        self.a = 0.0 if tau <= 0 else float(np.exp(-dt / tau))
        self.prev = np.zeros(n)
        self.omega = np.zeros(n)

    def reset(self, theta: np.ndarray, index: np.ndarray | slice | None = None) -> None:
        """Restart rigs ``index`` (default all) at angles ``theta`` (rad), speed estimate 0."""
        sel = slice(None) if index is None else index
        self.prev[sel] = theta
        self.omega[sel] = 0.0

    def update(self, theta: np.ndarray) -> np.ndarray:
        """Speed estimates (rad/s) after the angles ``theta`` (rad) of one more period (the state array)."""
        self.omega[:] = filtered_speed(self.omega, theta, self.prev, self.a, self.dt)
        self.prev[:] = theta
        return self.omega


@dataclass(frozen=True)
class MeasurementModel:
    """How the rig measures: encoder resolution, LVDT noise and the offline LVDT low-pass.

    Parameters
    ----------
    counts_per_rev : int, optional
        Encoder resolution (counts per revolution).  Default 8000.
    lvdt_noise_std : float, optional
        LVDT noise (m, standard deviation).  Default 3e-6.
    lvdt_lowpass_hz : float or None, optional
        Cut-off of the offline zero-phase LVDT low-pass (Hz); None: no filter.  Default 5.
    sample_rate_hz : float or None, optional
        Sample rate of the measurement (Hz); None: the simulation's.
    """

    counts_per_rev: int = DEFAULT_COUNTS_PER_REV
    lvdt_noise_std: float = DEFAULT_LVDT_NOISE
    lvdt_lowpass_hz: float | None = 5.0
    sample_rate_hz: float | None = None  # None: keep the simulation's rate


def measure_trajectory(traj, model: MeasurementModel = MeasurementModel(), seed: int | None = 0, description: str = ""):
    """A synthetic measurement of a simulated run, as the rig would record it.

    The run's Measurement effects (offsets, skew, ...), quantized encoder angles, LVDT readings with
    noise, the offline zero-phase LVDT low-pass.

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`drillgym.simulate`.
    model : MeasurementModel, optional
        The measurement chain; default the rig's.
    seed : int or None, optional
        Seed of the LVDT noise.
    description : str, optional
        Free text stored in the metadata.

    Returns
    -------
    TimeSeries
        The measurement in the interchange format (``t``, ``u``, ``theta_u``, ``theta_l``, ``x``, ``y``
        as the configuration has them; SI units).
    """
    from .io import TimeSeries

    rng = np.random.default_rng(seed)
    tu, tl, X, Y = traj.composition.measure(
        traj.theta_u, traj.theta_l, traj.x, traj.y, traj.parameter_vector, traj.omega_u, traj.omega_l
    )
    t = np.asarray(traj.t)
    fs = 1.0 / float(np.median(np.diff(t)))
    step = 1
    if model.sample_rate_hz:
        step = max(1, int(round(fs / model.sample_rate_hz)))
    cols = {"t": t, "u": np.asarray(traj.u), "theta_u": quantize_angle(tu, model.counts_per_rev)}
    if traj.config.has_lower:
        cols["theta_l"] = quantize_angle(tl, model.counts_per_rev)
    if traj.config.lateral_free:
        xm, ym = lvdt_measure(X, Y, model.lvdt_noise_std, rng)
        if model.lvdt_lowpass_hz:
            xm = lowpass_zero_phase(xm, fs, model.lvdt_lowpass_hz)
            ym = lowpass_zero_phase(ym, fs, model.lvdt_lowpass_hz)
        cols["x"], cols["y"] = xm, ym
    cols = {k: np.asarray(v, dtype=float)[::step] for k, v in cols.items()}
    meta = {
        "configuration": traj.config.label,
        "source": "simulation",
        "sample_rate_hz": fs / step,
        "description": description or "synthetic measurement",
        "counts_per_rev": model.counts_per_rev,
    }
    return TimeSeries(cols, meta, "<synthetic>")
