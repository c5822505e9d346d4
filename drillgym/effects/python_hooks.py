"""The composition's hooks as Python calls them: a kernel client template, compiled once per composition.

Not imported as it stands: :func:`hook_calls` writes a copy of this file into a composition's generated package
with its ``drillgym.kernels.*`` imports pointing there (:mod:`.foreign_client`), so numba compiles it once and
every later process loads it from the cache.  The hooks themselves are inlined helpers without a cache: called
from Python they compiled again in every process (about 0.5 s per hook and composition), and a loop over a
recording's samples through them cost a dispatch per sample.

* ``delay_of(p)``: the composition's transport delay of the command (s) at parameters ``p``; ``longest_delay(P)``:
  the longest over parameter rows;
* ``input_path(t, command, Y, p, cfg, dt, lags, at_motor)``: the command's path to the motor along a recording
  (:func:`drillgym.diagnosis.sparse.motor_voltage_along`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.kernels.hooks import N_EFFECT_STATES, N_STATE, hk_delay, hk_lag, hk_rhs

#: the mechanical states, before the effects'
N_MECH = N_STATE - N_EFFECT_STATES


@njit(cache=True)
def delay_of(p):
    return hk_delay(p)


@njit(cache=True)
def longest_delay(P):
    """The longest transport delay (s) over the parameter rows ``P``; 0 without rows."""
    d = 0.0
    for k in range(P.shape[0]):
        d = max(d, hk_delay(P[k]))
    return d


@njit(cache=True)
def input_path(t, command, Y, p, cfg, dt, lags, at_motor):  # pragma: no cover - compiled
    """The voltage at the motor at every sample (into ``at_motor``, V) for the delayed ``command`` (V) at the
    sample times ``t`` (s), the discs' states the rows of ``Y``; the effects' states (columns ``N_MECH:`` of
    ``Y``) written in place: each declared lag (columns ``lags``) starts at the steady state of the first
    command and is advanced exactly, any other state by its derivative (explicit Euler over ``dt``)."""
    n, m = Y.shape
    dy = np.zeros(m)
    y_next = np.zeros(m)
    for j in range(N_MECH, m):
        Y[0, j] = 0.0
    for _ in range(lags.shape[0]):  # each lag at the voltage entering it: one pass per lag of a chain
        y_next[:] = Y[0]
        hk_lag(0.0, command[0], Y[0], p, cfg, 1e12, y_next)
        for c in lags:
            Y[0, c] = y_next[c]
    for i in range(n):
        ti = t[i] - t[0]
        dy[:] = 0.0
        at_motor[i] = hk_rhs(ti, command[i], Y[i], p, cfg, dy)[0]
        if i + 1 < n:
            for j in range(m):
                y_next[j] = Y[i, j] + dt * dy[j]
            hk_lag(ti, command[i], Y[i], p, cfg, dt, y_next)
            for j in range(N_MECH, m):
                Y[i + 1, j] = y_next[j]
    return 0
