"""A voltage sequence played back as a compiled law, the sensors' reports kept in its state.

The excitation run of :mod:`controllers.evaluation.identify` (the quasi-random signal, one value per control
period) in the compiled closed loop: no Python call per period.  State rows (per lane): the period counter,
then per period the four measurements the law was given (``theta_u``, ``theta_l`` in rad, ``x``, ``y`` in m:
rows ``1 + 4 k + j``); constants: the voltages (V), one per period (the last is held past the end).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE

__all__ = ["playback_step", "playback_state", "played_measurements", "N_KEPT"]

#: measurement rows kept per period (theta_u, theta_l, x, y: the first rows of the loop's measurements)
N_KEPT = 4


@njit(LAW_SIGNATURE, cache=True)
def playback_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of every lane: keep the measurements, play the period's voltage."""
    k = int(X[0, 0])
    u = C[min(k, C.size - 1)]
    last = (X.shape[0] - 1) // N_KEPT
    for lane in range(U.size):
        if k < last:
            for j in range(N_KEPT):
                X[1 + N_KEPT * k + j, lane] = M[j, lane]
        X[0, lane] = k + 1.0
        U[lane] = u


def playback_state(periods: int, n: int) -> np.ndarray:
    """The law's state (1 + 4 periods, n) at the start: the counter at 0, room for every period's reports."""
    return np.zeros((1 + N_KEPT * int(periods), int(n)))


def played_measurements(X: np.ndarray) -> np.ndarray:
    """The reports kept so far: (periods run, 4, n) (theta_u, theta_l in rad; x, y in m)."""
    k = int(X[0, 0])
    return X[1 : 1 + N_KEPT * k].reshape(k, N_KEPT, X.shape[1])
