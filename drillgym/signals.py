"""Excitation signals for identification (report chapter 3, figure 3.1).

* :func:`quasi_random` — the estimation signal: random levels held for random
  times, low-passed so that its content lies below ``f_max`` (5 Hz, the rig's
  relevant dynamics), scaled to stay inside the amplifier range (±5 V).
* :func:`sum_of_sines` — the validation signal: a few sines of different
  frequencies (below ``f_max``) around an offset, inside the same range.

Both are seeded (same seed, same signal) and return ``(t, u)`` arrays in s
and V, which :func:`drillgym.simulate` accepts directly as its input and
:func:`write_input_file` writes as a DATA_FORMAT CSV with columns ``t, u``
(for the simulator and for the rig).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal as sps

from .errors import InputError
from .io.jsonfile import dumps_json

__all__ = ["quasi_random", "sum_of_sines", "write_input_file", "read_input_file", "U_MAX"]

U_MAX = 5.0  # V: amplifier range of the rig


#: Hz: the upper end of the excitation signals' band (the rig's torsional dynamics lie below it)
F_MAX_HZ = 5.0


def _fade_in(t: np.ndarray, u: np.ndarray, fade_s: float) -> np.ndarray:
    """Raised-cosine fade from 0 V over the first ``fade_s`` seconds (the rig starts at rest, 0 V)."""
    if fade_s <= 0:
        return u
    w = np.clip(t / fade_s, 0.0, 1.0)
    return u * 0.5 * (1.0 - np.cos(np.pi * w))


def _check(duration: float, rate_hz: float, amplitude: float, f_max: float) -> None:
    if not (np.isfinite(duration) and duration > 0):
        raise InputError(f"signal duration must be a positive number of seconds, got {duration!r}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"signal sample rate must be a positive number of Hz, got {rate_hz!r}")
    if not (0 < amplitude <= 50):
        raise InputError(f"signal amplitude must be in (0, 50] V, got {amplitude!r}")
    if not (np.isfinite(f_max) and f_max > 0):
        raise InputError(f"the signal's band f_max must be a positive number of Hz, got {f_max:g}")
    if not f_max < rate_hz / 2:
        raise InputError(
            f"a sample rate of {rate_hz:g} Hz cannot carry the signal's band up to f_max = {f_max:g} Hz "
            f"(its Nyquist rate is {rate_hz / 2:g} Hz): choose a rate above {2 * f_max:g} Hz"
        )


def _check_offset(amplitude: float, offset: float) -> None:
    if abs(offset) >= amplitude and offset != 0:
        raise InputError(
            f"offset {offset} V must be smaller in size than the amplitude {amplitude} V (the largest "
            f"|u|; the signal spans offset ± (amplitude - |offset|))"
        )


def quasi_random(
    duration: float,
    *,
    rate_hz: float = 1000.0,
    seed: int | None = 0,
    amplitude: float = U_MAX,
    offset: float = 0.0,
    f_max: float = F_MAX_HZ,
    hold: tuple[float, float] = (0.3, 3.0),
    fade_s: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """The report's quasi-random estimation signal.

    Random levels, each held for a random time uniform in ``hold``, then low-passed (zero-phase
    Butterworth at ``f_max``, so the content lies below it) and scaled into
    ``offset ± (amplitude - |offset|)``; the first ``fade_s`` seconds fade in from 0 V (the rig starts
    at rest).

    Parameters
    ----------
    duration : float
        Length of the signal (s).
    rate_hz : float, optional
        Sample rate (Hz).  Default 1000.
    seed : int or None, optional
        Seed of the random draws.
    amplitude : float, optional
        Largest |u| (V), e.g. the amplifier's range; must exceed |offset|.  Default 5.
    offset : float, optional
        Centre of the signal (V): it spans ``offset ± (amplitude - |offset|)``.
    f_max : float, optional
        Cut-off of the low-pass (Hz).  Default 5.
    hold : tuple of float, optional
        Range (min, max) of the time each level is held (s).  Default (0.3, 3).
    fade_s : float, optional
        Fade-in time from 0 V (s).  Default 0.5.

    Returns
    -------
    t : ndarray
        Time (s) from 0 at ``rate_hz``.
    u : ndarray
        Voltage (V).

    Raises
    ------
    InputError
        A non-positive duration, rate or amplitude, |offset| >= amplitude, or bad hold times.
    """
    _check(duration, rate_hz, amplitude, f_max)
    if not (0 < hold[0] <= hold[1]):
        raise InputError(f"hold times must satisfy 0 < min <= max, got {hold!r}")
    _check_offset(amplitude, offset)
    rng = np.random.default_rng(seed)
    n = int(round(duration * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    u = np.empty(n)
    i = 0
    while i < n:
        k = max(1, int(rng.uniform(*hold) * rate_hz))
        u[i : i + k] = rng.uniform(-1.0, 1.0)
        i += k
    sos = sps.butter(4, f_max, fs=rate_hz, output="sos")
    u = sps.sosfiltfilt(sos, u)
    span = amplitude - abs(offset)
    u = offset + span * u / max(np.max(np.abs(u)), 1e-12)
    return t, _fade_in(t, u, fade_s)


def sum_of_sines(
    duration: float,
    *,
    rate_hz: float = 1000.0,
    seed: int | None = 0,
    amplitude: float = U_MAX,
    offset: float = 0.0,
    frequencies: tuple[float, ...] = (0.05, 0.11, 0.23, 0.47, 0.9, 1.7),
    f_max: float = F_MAX_HZ,
    fade_s: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Sum-of-sines validation signal.

    Equal-amplitude sines with seeded random phases, scaled into ``offset ± (amplitude - |offset|)``,
    faded in from 0 V over ``fade_s`` seconds.

    Parameters
    ----------
    duration : float
        Length of the signal (s).
    rate_hz : float, optional
        Sample rate (Hz).  Default 1000.
    seed : int or None, optional
        Seed of the random draws.
    amplitude : float, optional
        Largest |u| (V), e.g. the amplifier's range; must exceed |offset|.  Default 5.
    offset : float, optional
        Centre of the signal (V): it spans ``offset ± (amplitude - |offset|)``.
    frequencies : tuple of float, optional
        Frequencies of the sines (Hz), all below ``f_max``.
    f_max : float, optional
        Upper bound of the frequencies (Hz).  Default 5.
    fade_s : float, optional
        Fade-in time from 0 V (s).  Default 0.5.

    Returns
    -------
    t : ndarray
        Time (s) from 0 at ``rate_hz``.
    u : ndarray
        Voltage (V).

    Raises
    ------
    InputError
        Bad duration, rate, amplitude, offset or frequencies.
    """
    _check(duration, rate_hz, amplitude, f_max)
    _check_offset(amplitude, offset)
    f = np.asarray(frequencies, dtype=float)
    if f.size == 0 or np.any(f <= 0) or np.any(f >= f_max):
        raise InputError(f"frequencies must be positive and below f_max = {f_max} Hz, got {tuple(frequencies)}")
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0.0, 2 * np.pi, f.size)
    t = np.arange(int(round(duration * rate_hz)) + 1) / rate_hz
    u = np.sin(2 * np.pi * f[None, :] * t[:, None] + phases[None, :]).sum(axis=1)
    span = amplitude - abs(offset)
    u = offset + span * u / max(np.max(np.abs(u)), 1e-12)
    return t, _fade_in(t, u, fade_s)


def write_input_file(path: str | Path, t: np.ndarray, u: np.ndarray, description: str = "") -> Path:
    """Write an input signal as a DATA_FORMAT CSV (columns ``t, u``; metadata line first).

    Parameters
    ----------
    path : str or path
        Output file.
    t : ndarray
        Time (s), 1-D, strictly increasing.
    u : ndarray
        Voltage (V), same shape.
    description : str, optional
        Free text stored in the metadata.

    Returns
    -------
    Path
        The path written.
    """
    t = np.asarray(t, dtype=float)
    u = np.asarray(u, dtype=float)
    if t.shape != u.shape or t.ndim != 1:
        raise InputError(f"t and u must be 1-D arrays of one length, got shapes {t.shape} and {u.shape}")
    if np.any(np.diff(t) <= 0):
        raise InputError("signal time must be strictly increasing")
    path = Path(path)
    meta = {
        "source": "signal",
        "description": description,
        "sample_rate_hz": round(float(1.0 / np.median(np.diff(t))), 6) if t.size > 1 else None,
    }
    with path.open("w", encoding="utf-8") as fh:
        fh.write(f"# meta: {dumps_json(meta)}\n")
        fh.write("t,u\n")
        for a, b in zip(t, u):
            fh.write(f"{float(a)!r},{float(b)!r}\n")
    return path


def read_input_file(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read the ``t, u`` columns of a DATA_FORMAT CSV (an input file or a full recording).

    Parameters
    ----------
    path : str or path
        The file.

    Returns
    -------
    t, u : ndarray
        Time (s) and voltage (V).
    """
    from .io import read_input_signal

    return read_input_signal(path)
