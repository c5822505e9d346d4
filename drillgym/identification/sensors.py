"""The composition's measurement effects run backwards: from what the sensors read to the rig's state.

A recording holds the channels *as the sensors read them* (LVDT offsets, skew, any user
Measurement effect applied).  Multiple shooting restarts the model from the recording, so the
readings at a segment start must be turned back into the mechanical quantities.  The
measurement map h: (θu, θl, X, Y) -> readings is known only as compiled code
(:meth:`drillgym.effects.Composition.measure`), so it is inverted numerically: Newton's method
with a finite-difference Jacobian, per sample (4 × 4), a few iterations (exact in one for the
affine maps of the library).  Rates go through the inverse Jacobian at the solution.
"""

from __future__ import annotations

import numpy as np

from ..effects import Composition

__all__ = ["invert_measurement"]

_H = 1e-7  # finite-difference step (rad or m) of the Jacobian
_ITER = 6


def invert_measurement(
    comp: Composition, readings: np.ndarray, rates: np.ndarray | None, vec: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """The states and rates whose measurement is the readings.

    Parameters
    ----------
    comp : Composition
        The composition whose Measurement effects the readings went through.
    readings : numpy.ndarray
        (n, 4) columns θu (rad), θl (rad), X (m), Y (m) as read by the sensors.
    rates : numpy.ndarray or None
        (n, 4) their measured time derivatives (per s); the first two are the speeds a Measurement effect that
        asks for ``omega_u`` / ``omega_l`` reads (None: 0).
    vec : numpy.ndarray
        The composition's parameter vector.

    Returns
    -------
    tuple of (numpy.ndarray, numpy.ndarray or None)
        (n, 4) true θu, θl, X, Y and (n, 4) true rates (the measured rates through the inverse Jacobian;
        entries measured exactly 0 on a channel the inversion does not mix stay 0).
    """
    m = np.asarray(readings, dtype=float)
    if not comp.has_measurement:
        return m.copy(), None if rates is None else np.asarray(rates, dtype=float).copy()
    s = m.copy()
    J = np.empty((m.shape[0], 4, 4))
    # a reading that depends on the direction of motion gets the discs' speeds as measured
    wu, wl = (np.zeros(m.shape[0]),) * 2 if rates is None else (np.asarray(rates, dtype=float)[:, j] for j in (0, 1))
    for _ in range(_ITER):
        h0 = np.column_stack(comp.measure(s[:, 0], s[:, 1], s[:, 2], s[:, 3], vec, wu, wl))
        for j in range(4):
            sp = s.copy()
            sp[:, j] += _H
            J[:, :, j] = (np.column_stack(comp.measure(sp[:, 0], sp[:, 1], sp[:, 2], sp[:, 3], vec, wu, wl)) - h0) / _H
        r = h0 - m
        s = s - np.linalg.solve(J, r[:, :, None])[:, :, 0]
        if np.max(np.abs(r)) < 1e-12:
            break
    if rates is None:
        return s, None
    rt = np.asarray(rates, dtype=float)
    out = np.linalg.solve(J, rt[:, :, None])[:, :, 0]
    mixed = np.abs(J - np.eye(4)[None]).max(axis=1) > 1e-6  # (n, 4): column j of J differs from identity
    keep_zero = (rt == 0.0) & ~mixed
    out[keep_zero] = 0.0
    return s, out
