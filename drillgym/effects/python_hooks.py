"""The composition's hooks as Python calls them: a kernel client template, compiled once per composition.

Not imported as it stands: :func:`hook_calls` writes a copy of this file into a composition's generated package
with its ``drillgym.kernels.*`` imports pointing there (:mod:`.foreign_client`), so numba compiles it once and
every later process loads it from the cache.  The hooks themselves are inlined helpers without a cache: called
from Python they compiled again in every process (about 0.5 s per hook and composition), and a loop over a
recording's samples through them cost a dispatch per sample.

* ``delay_of(p)``: the composition's transport delay of the command (s) at parameters ``p``; ``longest_delay(P)``:
  the longest over parameter rows;
* ``input_path(t, command, Y, p, cfg, dt, lags, at_motor)``: the command's path to the motor along a recording
  (:func:`drillgym.diagnosis.sparse.motor_voltage_along`);
* ``lag_states(...)``: the lag states along a free run from a record's start when they are all the effect states
  and the input alone drives them (:meth:`drillgym.identification.segmented.SegmentedModel`'s segment starts).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.kernels.commands import delay_line_read, delay_line_step
from drillgym.kernels.hooks import N_EFFECT_STATES, N_STATE, hk_delay, hk_lag, hk_lag_start, hk_rhs

#: the mechanical states, before the effects'
N_MECH = N_STATE - N_EFFECT_STATES


@njit(cache=True, error_model="numpy")
def delay_of(p):
    return hk_delay(p)


@njit(cache=True, error_model="numpy")
def longest_delay(P):
    """The longest transport delay (s) over the parameter rows ``P``; 0 without rows."""
    d = 0.0
    for k in range(P.shape[0]):
        d = max(d, hk_delay(P[k]))
    return d


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def lag_states(U, P, cfg, dt, n_steps, rec, starts, X0, HIST, HEAD, out):  # pragma: no cover - compiled
    """The declared lag states of a free run from the record's start (every effect state a lag driven by the
    input alone) at the samples ``starts`` (every ``rec`` steps of ``dt`` s), into ``out`` (B, len(starts),
    n_effect_states): per parameter row ``P[b]``, the command ``U[b, i]`` held over step ``i`` through the
    delay line (``HIST[b]``, ``HEAD[b]``), the lags started at the first command held (states NaN in ``X0``)
    and advanced exactly, as the kernels' steps advance them (a step split at an event of the discs, there,
    gives the same states to round-off).  The discs are not simulated: nothing on the input's path reads
    them."""
    B = P.shape[0]
    m = X0.shape[1]
    y = np.empty(m)
    yo = np.empty(m)
    for b in range(B):
        for j in range(m):
            y[j] = X0[b, j]
        p = P[b]
        hist = HIST[b]
        head = HEAD[b : b + 1]
        ub = U[b]
        u = delay_line_step(hist, head, ub[0], p, dt) if n_steps > 0 else delay_line_read(hist, head, ub[0], p, dt)
        hk_lag_start(0.0, u, y, p, cfg)
        k = 0
        while k < starts.shape[0] and starts[k] == 0:
            for j in range(N_MECH, m):
                out[b, k, j - N_MECH] = y[j]
            k += 1
        t = 0.0
        for i in range(n_steps):
            if i > 0:
                u = delay_line_step(hist, head, ub[i] if ub.shape[0] > 1 else ub[0], p, dt)
            for j in range(m):
                yo[j] = y[j]
            hk_lag(t, u, y, p, cfg, dt, yo)
            for j in range(N_MECH, m):
                y[j] = yo[j]
            t = (i + 1) * dt
            while k < starts.shape[0] and starts[k] * rec == i + 1:
                for j in range(N_MECH, m):
                    out[b, k, j - N_MECH] = y[j]
                k += 1
    return 0
