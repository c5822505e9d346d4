"""The noise of an angle reading, read from the recording itself.

An encoder reports whole counts: every difference between its samples is a whole number of counts, and its
reading's error is the count's rounding, one count / √12 (the count found by :func:`encoder_count`).  A reading
that lies on no lattice of counts carries noise beyond them (a reading interpolated or filtered, electrical noise
added after the count, an analog sensor): its error is read from the samples' high-frequency scatter instead
(:func:`scatter`, the robust spread of the fourth differences, which a motion sampled at the comparison grid
hardly reaches).  One estimate serves the fit's channel scales, the speed estimates' noise and the comparison's
noise units, so a recording with noise beyond its counts is not read as a misfit of tens of noise units.
"""

from __future__ import annotations

import math

import numpy as np

from ..model_files import Encoders

__all__ = [
    "MIN_COUNT_RAD", "ANGLE_FLOOR_RAD", "encoder_count", "scatter", "angle_noise", "finest_angle_noise", "encoders_of",
    "noisy_lattice", "recording_encoders",
]  # fmt: skip

MIN_COUNT_RAD = 1e-7  # rad: differences below this are round-off, not encoder counts (1e-7 rad ~ 6e7 counts/rev)
ANGLE_FLOOR_RAD = 1e-4  # rad: no angle reading is taken as finer than this
_ORDER = 4  # the differences' order of the scatter
_GAIN = math.sqrt(sum(math.comb(_ORDER, k) ** 2 for k in range(_ORDER + 1)))  # white noise's gain through them
#: the farthest (in counts) a difference may lie from a whole number of counts: the tolerance grows with the
#: multiples for their round-off, never so far that noise off any lattice would pass for counts far below it
_MAX_OFF_COUNT = 0.05
_MAD = 1.4826  # the median absolute deviation of a normal variable, in standard deviations


def encoder_count(theta: np.ndarray, max_multiple: int = 50) -> float | None:
    """The encoder count (rad) of a recorded angle, or None where it lies on no lattice of counts.

    Every difference between samples of a quantized angle is a whole number of counts, but on a coarse grid
    (or when the disc never stops) even the smallest difference can be several counts: the count is the largest
    ``d_min / k`` (k <= ``max_multiple``) of which all differences are whole multiples, ``d_min`` the smallest
    difference above round-off (:data:`MIN_COUNT_RAD`).

    Parameters
    ----------
    theta : numpy.ndarray
        The angle (rad).
    max_multiple : int, optional
        The largest number of counts the smallest difference may hold.  Default 50.

    Returns
    -------
    float or None
        The count (rad); None if the angle never changes or its differences are whole multiples of no count.
    """
    return _count(np.abs(np.diff(np.asarray(theta, dtype=float))), max_multiple)


def _count(d: np.ndarray, max_multiple: int = 50) -> float | None:
    """:func:`encoder_count` of the samples' absolute differences ``d`` (rad)."""
    d = d[d > MIN_COUNT_RAD]
    if not d.size:
        return None
    d_min = float(d.min())
    for k in range(1, max_multiple + 1):
        q = d_min / k
        m = d / q
        if np.max(np.abs(m - np.round(m))) < min(1e-3 * max(1.0, float(m.max()) * 1e-3), _MAX_OFF_COUNT):
            return q
    return None


def scatter(theta: np.ndarray) -> float:
    """The standard deviation (rad) of white noise on a sampled angle: the median absolute deviation of its
    fourth differences, over their gain (robust to the few samples a stick/slip transition moves).

    Parameters
    ----------
    theta : numpy.ndarray
        The angle (rad), at least 6 samples.

    Returns
    -------
    float
        The noise's standard deviation (rad); 0 for fewer samples.
    """
    theta = np.asarray(theta, dtype=float)
    if theta.size <= _ORDER + 1:
        return 0.0
    d = np.diff(theta, _ORDER)
    return float(_MAD * np.median(np.abs(d - np.median(d))) / _GAIN)


def angle_noise(theta: np.ndarray) -> float | None:
    """The standard deviation (rad) of an angle reading's error (module doc): one count / √12 on a lattice of
    counts, else the samples' scatter.

    Parameters
    ----------
    theta : numpy.ndarray
        The angle (rad).

    Returns
    -------
    float or None
        The reading's noise (rad); None for an angle that never changes (it tells nothing).
    """
    d = np.abs(np.diff(np.asarray(theta, dtype=float)))
    if not np.any(d > MIN_COUNT_RAD):
        return None
    q = _count(d)
    return q / math.sqrt(12.0) if q is not None else scatter(theta)


def finest_angle_noise(readings) -> float | None:
    """The noise (rad) of the finest of several angle readings (:func:`angle_noise`; one encoder type on both
    discs).

    Parameters
    ----------
    readings : iterable of numpy.ndarray
        The angles (rad).

    Returns
    -------
    float or None
        The noise (rad); None where no reading changes.
    """
    return min((n for n in map(angle_noise, readings) if n is not None), default=None)


#: counts per revolution :func:`noisy_lattice` looks for (a coarser encoder is read exactly, a finer one's count is
#: below any noise worth telling a controller)
LATTICE_COUNTS = (256, 65536)
_LATTICE_BINS = 1 << 18  # histogram bins over a revolution (24 urad: the binning keeps 0.99 of R at 8192 counts)
_RAYLEIGH_MIN = 100.0  # n R^2 above which a lattice is taken (about exp(-100) for a reading on none)
_PEAK_RATIO = 3.0  # R at the lattice's count over R at the counts beside it: a sharp peak, not a bunched angle


def noisy_lattice(theta: np.ndarray) -> tuple[int, float] | None:
    """The counts per revolution and the white noise (rad) of an encoder whose readings carry noise after the count.

    An encoder of N counts per revolution reads whole counts 2 pi / N, whatever offset its zero has; white noise of
    standard deviation s added after the count leaves the readings on that lattice in distribution: the angle
    modulo one revolution has the Fourier coefficient R(N) = exp(-N^2 s^2 / 2) at N (the characteristic function of
    the noise), and about 0 at the counts N is not a divisor of.  One FFT of the readings' histogram over a
    revolution gives R at every whole count; the coarsest count whose Rayleigh statistic n R^2 is significant and
    whose R stands out of the counts beside it (a sharp peak: a disc parked at one angle bunches its readings and
    raises R at every count alike) is the encoder's, and s = sqrt(-2 ln R) / N.

    Parameters
    ----------
    theta : numpy.ndarray
        The angle (rad); the disc must turn at least twice (the lattice's period in counts is then sharp).

    Returns
    -------
    (int, float) or None
        Counts per revolution and noise (rad); None where no lattice of :data:`LATTICE_COUNTS` shows.
    """
    theta = np.asarray(theta, dtype=float)
    theta = theta[np.isfinite(theta)]
    if theta.size < 100 or np.ptp(theta) < 4.0 * math.pi:
        return None
    phase = np.mod(theta, 2.0 * math.pi) * (_LATTICE_BINS / (2.0 * math.pi))
    hist = np.bincount(np.minimum(phase.astype(np.int64), _LATTICE_BINS - 1), minlength=_LATTICE_BINS)
    lo, hi = LATTICE_COUNTS
    R = np.abs(np.fft.rfft(hist)[: hi + 5]) / theta.size
    k = np.arange(lo, hi + 1)
    beside = np.maximum.reduce([R[k + d] for d in (-4, -3, -2, 2, 3, 4)])
    found = k[(theta.size * R[k] ** 2 > _RAYLEIGH_MIN) & (R[k] > _PEAK_RATIO * beside)]
    if not found.size:
        return None
    n = int(found[0])
    return n, math.sqrt(max(-2.0 * math.log(min(R[n], 1.0)), 0.0)) / n


def encoders_of(readings) -> Encoders | None:
    """The encoders a recording's angle readings show (one encoder type on both discs): the finest reading's
    resolution where it lies on a lattice of counts (the nearest whole counts per revolution, when the count is
    2 pi over one to within 0.1 %); else, where noise after the count hides the lattice from the samples'
    differences, the lattice its distribution still shows (:func:`noisy_lattice`, the quieter reading's) with that
    noise; else its error as white noise (:func:`angle_noise`).

    Parameters
    ----------
    readings : iterable of numpy.ndarray or None
        The angles (rad); None for a channel the recording does not hold.

    Returns
    -------
    drillgym.model_files.Encoders or None
        None where no reading changes (it tells nothing).
    """
    angles = [np.asarray(r, dtype=float) for r in readings if r is not None]
    counts = [q for q in map(encoder_count, angles) if q is not None]
    if counts:
        q = min(counts)
        cpr = round(2.0 * math.pi / q)
        if cpr >= 1 and abs(2.0 * math.pi / cpr - q) <= 1e-3 * q:
            return Encoders(cpr, 0.0)
    lattices = [lat for lat in map(noisy_lattice, angles) if lat is not None]
    if lattices:
        cpr, noise = min(lattices, key=lambda lat: lat[1])  # the quieter reading tells the count best
        return Encoders(cpr, noise)
    noise = finest_angle_noise(angles)
    return None if noise is None else Encoders(None, noise)


def recording_encoders(recording, known: Encoders | None = None) -> Encoders | None:
    """The encoders a recording's angle columns show (:func:`encoders_of` of ``theta_u`` and ``theta_l``), or
    ``known`` (the starting model's) where its readings show none; every route that writes a model from a
    recording takes them from here.

    Parameters
    ----------
    recording : drillgym.io.TimeSeries or None
        The recording; None: ``known``.
    known : Encoders, optional
        The encoders the model the identification started from carries.

    Returns
    -------
    drillgym.model_files.Encoders or None
    """
    if recording is None:
        return known
    return encoders_of(recording.columns.get(c) for c in ("theta_u", "theta_l")) or known
