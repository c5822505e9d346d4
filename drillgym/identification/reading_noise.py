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


def encoders_of(readings) -> Encoders | None:
    """The encoders a recording's angle readings show (one encoder type on both discs): the finest reading's
    resolution where it lies on a lattice of counts (the nearest whole counts per revolution, when the count is
    2 pi over one to within 0.1 %), else its error as white noise (:func:`angle_noise`).

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
    noise = finest_angle_noise(angles)
    return None if noise is None else Encoders(None, noise)
