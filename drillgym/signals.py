"""Excitation signals for identification (report chapter 3, figure 3.1).

* :func:`quasi_random` — the estimation signal: random levels held for random
  times, low-passed so that its content lies below ``f_max`` (5 Hz, the rig's
  relevant dynamics), scaled to stay inside the amplifier range (±5 V).
* :func:`sum_of_sines` — the validation signal: a few sines of different
  frequencies (below ``f_max``) around an offset, inside the same range.

Both are seeded (same seed, same signal) and return ``(t, u)`` arrays in s
and V, which :func:`drillgym.simulate` accepts directly as its input and
:func:`write_input_file` writes as a CSV (docs/data_format.md) with columns ``t, u``
(for the simulator and for the rig).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from scipy import signal as sps

from .errors import InputError
from .io import U_LIMIT_FILE
from .io.jsonfile import dumps_json
from .io.outputs import check_output_file
from .io.paths import written_whole
from .run_setup import real_number, real_numbers, whole_number

__all__ = [
    "quasi_random",
    "sum_of_sines",
    "check_signal",
    "write_input_file",
    "read_input_file",
    "U_MAX",
    "MAX_SAMPLES",
]

U_MAX = 5.0  # V: amplifier range of the rig


#: Hz: the upper end of the excitation signals' band (the rig's torsional dynamics lie below it)
F_MAX_HZ = 5.0


def _fade_in(t: np.ndarray, u: np.ndarray, fade_s: float) -> np.ndarray:
    """Raised-cosine fade from 0 V over the first ``fade_s`` seconds (the rig starts at rest, 0 V)."""
    if fade_s <= 0:
        return u
    w = np.clip(t / fade_s, 0.0, 1.0)
    return u * 0.5 * (1.0 - np.cos(np.pi * w))


#: most samples one signal may have (about 2 GB as CSV)
MAX_SAMPLES = 50_000_000


def check_signal(
    duration: Any,
    rate_hz: Any,
    amplitude: Any,
    offset: Any = 0.0,
    seed: Any = 0,
    f_max: Any = F_MAX_HZ,
    *,
    names: Mapping[str, str] | None = None,
) -> None:
    """Refuse, before anything is generated, settings no signal can have.

    Parameters
    ----------
    duration : float
        Length (s): positive, finite.
    rate_hz : float
        Sample rate (Hz): above twice ``f_max``; ``duration * rate_hz`` between 2 and :data:`MAX_SAMPLES`.
    amplitude : float
        Largest |u| (V): in (0, 50].
    offset : float, optional
        Centre (V): finite and smaller in size than ``amplitude``.
    seed : int or None, optional
        Seed: None or a whole number >= 0.
    f_max : float, optional
        The band's upper end (Hz).
    names : mapping of str to str, optional
        The name each argument has for the user (``{"rate_hz": "--rate"}`` on the command line); default the
        argument names.

    Raises
    ------
    InputTypeError
        A setting that is not a number (a string, a bool, None).
    InputError
        A setting out of its range.
    """
    name = {k: k for k in ("duration", "rate_hz", "amplitude", "offset", "seed", "f_max")} | dict(names or {})
    duration = real_number(name["duration"], duration, "s")
    rate_hz = real_number(name["rate_hz"], rate_hz, "Hz")
    amplitude = real_number(name["amplitude"], amplitude, "V")
    offset = real_number(name["offset"], offset, "V")
    f_max = real_number(name["f_max"], f_max, "Hz")
    if not (math.isfinite(duration) and duration > 0):
        raise InputError(f"{name['duration']} must be a positive number of seconds, got {duration:g}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"{name['rate_hz']} must be a positive number of Hz, got {rate_hz:g}")
    if duration * rate_hz > MAX_SAMPLES:
        raise InputError(
            f"{name['duration']} {duration:g} s at {name['rate_hz']} {rate_hz:g} Hz is {duration * rate_hz:.3g} "
            f"samples, more than {MAX_SAMPLES:.0e}: shorten {name['duration']} or lower {name['rate_hz']}"
        )
    if duration * rate_hz < 2:
        raise InputError(
            f"{name['duration']} {duration:g} s at {name['rate_hz']} {rate_hz:g} Hz gives fewer than 2 samples"
        )
    if not (math.isfinite(f_max) and f_max > 0):
        raise InputError(f"the signal's band {name['f_max']} must be a positive number of Hz, got {f_max:g}")
    if not f_max < rate_hz / 2:
        raise InputError(
            f"{name['rate_hz']} {rate_hz:g} Hz cannot carry the signal's band up to {f_max:g} Hz (its Nyquist "
            f"rate is {rate_hz / 2:g} Hz): choose a rate above {2 * f_max:g} Hz"
        )
    if not (math.isfinite(amplitude) and 0 < amplitude <= U_LIMIT_FILE):
        raise InputError(f"{name['amplitude']} must be in (0, {U_LIMIT_FILE:g}] V, got {amplitude:g}")
    if not math.isfinite(offset):
        raise InputError(f"{name['offset']} must be a finite number of volts, got {offset:g}")
    if offset != 0 and not abs(offset) < amplitude:
        raise InputError(
            f"{name['offset']} {offset:g} V must be smaller in size than {name['amplitude']} {amplitude:g} V "
            f"(the signal spans offset ± (amplitude - |offset|))"
        )
    if seed is not None:
        whole_number(name["seed"], seed, 0)


def _check_fade(fade_s: Any) -> None:
    fade_s = real_number("fade_s", fade_s, "s")
    if not (math.isfinite(fade_s) and fade_s >= 0):
        raise InputError(f"fade_s must be a number of seconds >= 0, got {fade_s:g}")


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
    check_signal(duration, rate_hz, amplitude, offset, seed, f_max)
    _check_fade(fade_s)
    lo, hi = real_numbers("hold", hold, "s") if np.size(hold) == 2 else (math.nan, math.nan)
    if not (0 < lo <= hi):
        raise InputError(f"hold must be two times (s) with 0 < min <= max, got {hold!r}")
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
    check_signal(duration, rate_hz, amplitude, offset, seed, f_max)
    _check_fade(fade_s)
    f = real_numbers("frequencies", frequencies, "Hz")
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
    """Write an input signal as a CSV of docs/data_format.md (columns ``t, u``; metadata line first).

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
    t = real_numbers("t", t, "s")
    u = real_numbers("u", u, "V")
    if t.shape != u.shape or t.ndim != 1:
        raise InputError(f"t and u must be 1-D arrays of one length, got shapes {t.shape} and {u.shape}")
    if np.any(np.diff(t) <= 0):
        raise InputError("signal time must be strictly increasing")
    if u.size and np.max(np.abs(u)) > U_LIMIT_FILE:
        raise InputError(f"u must stay within ±{U_LIMIT_FILE:g} V, got {float(np.max(np.abs(u))):g} V")
    path = check_output_file(path, "path", suffixes=(".csv",))
    meta = {
        "source": "signal",
        "description": description,
        "sample_rate_hz": round(float(1.0 / np.median(np.diff(t))), 6) if t.size > 1 else None,
    }
    with written_whole(path, "the input signal") as fh:
        fh.write(f"# meta: {dumps_json(meta)}\n")
        fh.write("t,u\n")
        for a, b in zip(t, u):
            fh.write(f"{float(a)!r},{float(b)!r}\n")
    return path


def read_input_file(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read the ``t, u`` columns of a CSV of docs/data_format.md (an input file or a full recording).

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
