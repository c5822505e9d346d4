"""Where a candidate effect's fit starts.

A local least-squares fit from an effect's guess finds the nearest minimum.  On a rig that sticks hard
the misfit of a stick-slip recording is rugged in the timing parameters: an independent rig's 37 ms input
delay (friction smoothing 0.1 mrad/s) was fitted as 14 ms from the 5 ms guess, explaining a quarter of the
residual where the true value explains 99.99 % of it, and the selection found nothing.  So every fresh
candidate is first evaluated, in one batch of the simulator's lanes, at a spread of values around its guess
(within a few of its declared scales, inside its bounds), and its fit starts from the best of them.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import qmc

from ..effects import Effect

__all__ = ["search_points", "SPAN_SCALES", "N_POINTS"]

#: the search reaches this many of a parameter's declared ``scale`` either side of its guess
SPAN_SCALES = 4.0
#: points besides the guess (a one-parameter effect: evenly spaced; more: a scrambled Sobol sequence)
N_POINTS = 8


def search_points(effect: type[Effect], n: int = N_POINTS, span: float = SPAN_SCALES, seed: int = 0) -> np.ndarray:
    """Parameter rows to start an effect's fit from: its guess, then points spread around it.

    Parameters
    ----------
    effect : Effect class
        The effect (its k parameters in declared order).
    n : int, optional
        Points besides the guess.
    span : float, optional
        Their spread, in the parameters' scales.
    seed : int, optional
        The random seed (the points are deterministic for a given seed).  Default 0.

    Returns
    -------
    numpy.ndarray
        (n + 1, k) rows: the guess first, then the points clipped into the bounds (repeated rows removed,
        so fewer may come back).
    """
    ps = effect.parameters
    k = len(ps)
    guess = np.array([p.guess for p in ps], dtype=float)
    scale = np.array([p.scale for p in ps], dtype=float)
    lo = np.array([p.lo for p in ps], dtype=float)
    hi = np.array([p.hi for p in ps], dtype=float)
    if k == 0:
        return np.zeros((1, 0))
    if k == 1:
        u = np.linspace(-1.0, 1.0, n)[:, None]
    else:
        m = 1 << int(np.ceil(np.log2(max(n, 2))))
        u = 2.0 * qmc.Sobol(k, scramble=True, seed=seed).random(m)[:n] - 1.0
    rows = np.clip(guess + span * scale * u, lo, hi)
    rows = np.vstack([guess, rows])
    _, first = np.unique(np.round(rows, 12), axis=0, return_index=True)
    return rows[np.sort(first)]
