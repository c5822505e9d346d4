"""Kernel template: fixed-step Runge-Kutta with exact, event-driven stick-slip (scalar path).

See :mod:`drillgym.integrators` for the method (Leine's switch model made exact with
event location inside the fixed step).  This template is specialised per composition of
effects (:mod:`drillgym.effects.codegen`); the right-hand side and switching logic come
from the specialised :mod:`drillgym.kernels.model`.

Transport delay (a Delay effect): every trajectory carries a delay line ``hist`` of the
commanded voltages of its last steps and ``head`` (index of the newest; -1 = empty: the
first command fills it, i.e. before the run the command was held at its first value).  At
step i the motor sees u(t_i - d), linear between the per-step commands (as
``numpy.interp`` of the zero-order-hold sequence).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from drillgym.dynamics import S_WL, S_WU, lateral_free
from drillgym.kernels.hooks import HAS_DELAY, N_STATE, hk_delay
from drillgym.kernels.model import (
    event_values, initial_modes, lower_stick_bounds, record, resolve_modes, state_derivative, upper_stick_bounds,
)
from drillgym.dynamics import brake_on

MAX_EVENTS_PER_STEP = 8
ILLINOIS_ITERATIONS = 6


@njit(cache=True)
def alloc_work(n_stages: int):
    """Work arrays of ``hybrid_step`` for a tableau of n_stages:
    (K stage derivatives + end derivative, ytmp, k1, ynew, fric, ftmp, g0, g1)."""
    K = np.zeros((n_stages + 1, N_STATE))
    return (K, np.zeros(N_STATE), np.zeros(N_STATE), np.zeros(N_STATE), np.zeros(2), np.zeros(2), np.zeros(2),
            np.zeros(2))


@njit(cache=True, _nrt=False)
def delay_line_step(hist, head, u, p, dt):
    """Push the command u (V) of a new step into the delay line and return what the motor sees
    (u itself without a Delay effect)."""
    if not HAS_DELAY:
        return u
    L = hist.shape[0]
    h = head[0]
    if h < 0:
        for i in range(L):
            hist[i] = u
        h = 0
    else:
        h += 1
        if h >= L:
            h = 0
        hist[h] = u
    head[0] = h
    return delay_line_read(hist, head, u, p, dt)


@njit(cache=True, _nrt=False)
def delay_line_read(hist, head, u, p, dt):
    """What the motor sees now (without pushing a new command); u when the line is empty."""
    if not HAS_DELAY:
        return u
    h = head[0]
    if h < 0:
        return u
    L = hist.shape[0]
    m = max(hk_delay(p), 0.0) / dt
    n = int(m)
    f = m - n
    if n > L - 2:  # the caller sizes the line; never read past it
        n = L - 2
        f = 1.0
    i0 = h - n
    if i0 < 0:
        i0 += L
    i1 = i0 - 1
    if i1 < 0:
        i1 += L
    return (1.0 - f) * hist[i0] + f * hist[i1]


@njit(cache=True, _nrt=False)
def active_states(cfg):
    """Number of leading state entries that evolve: 4 (angles, speeds) unless the disc moves
    laterally or the effects carry states (then all N_STATE)."""
    if lateral_free(cfg) or N_STATE > 8:
        return N_STATE
    return 4


@njit(cache=True, fastmath=True, _nrt=False)
def _rk_step(t, y0, k1, mode, u, p, cfg, eps, h, A, b, c, K, ytmp, y_out, fric):
    """One explicit RK step of size h from (t, y0) with derivative k1 at y0; result in y_out.

    Only the first ``active_states`` entries evolve; the others are copied.  The
    4-stage tableau (classical RK4, sparse) takes an unrolled path, the others
    (DP5) the general Butcher loop.
    """
    s = b.shape[0]
    n = active_states(cfg)
    for j in range(n, y0.shape[0]):
        ytmp[j] = y0[j]
        y_out[j] = y0[j]
    if s == 4:
        k2 = K[1]
        k3 = K[2]
        k4 = K[3]
        hh = 0.5 * h
        for j in range(n):
            ytmp[j] = y0[j] + hh * k1[j]
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k2, fric)
        for j in range(n):
            ytmp[j] = y0[j] + hh * k2[j]
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k3, fric)
        for j in range(n):
            ytmp[j] = y0[j] + h * k3[j]
        state_derivative(t + h, ytmp, mode, u, p, cfg, eps, k4, fric)
        h6 = h / 6.0
        for j in range(n):
            y_out[j] = y0[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
        return
    for j in range(n):
        K[0, j] = k1[j]
    for i in range(1, s):
        for j in range(n):
            acc = 0.0
            for l in range(i):
                acc += A[i, l] * K[l, j]
            ytmp[j] = y0[j] + h * acc
        state_derivative(t + c[i] * h, ytmp, mode, u, p, cfg, eps, K[i], fric)
    for j in range(n):
        acc = 0.0
        for i in range(s):
            acc += b[i] * K[i, j]
        y_out[j] = y0[j] + h * acc


@njit(cache=True, _nrt=False)
def hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, h, A, b, c, K, ytmp, ynew, g0, g1, ftmp):
    """Advance (t, y) by h with event-driven mode switching.

    On entry k1/fric hold the derivative and friction torques at (t, y) with the
    current modes and input u; on exit they hold them at the new state (so the
    next step reuses them).  Returns the number of mode switches.
    """
    remaining = h
    n_events = 0
    n = y.shape[0]
    kend = K[K.shape[0] - 1]
    fend0 = 0.0
    fend1 = 0.0
    while True:
        _rk_step(t, y, k1, mode, u, p, cfg, eps, remaining, A, b, c, K, ytmp, ynew, ftmp)
        state_derivative(t + remaining, ynew, mode, u, p, cfg, eps, kend, ftmp)
        fend0 = ftmp[0]
        fend1 = ftmp[1]
        if eps > 0.0 or n_events >= MAX_EVENTS_PER_STEP:
            break
        event_values(t + remaining, ynew, mode, ftmp, p, cfg, g1)
        if g1[0] >= 0.0 and g1[1] >= 0.0:
            break
        event_values(t, y, mode, fric, p, cfg, g0)
        # earliest crossing by linear estimate
        j = -1
        tau_best = 2.0
        for q in range(2):
            if g1[q] < 0.0:
                tau = g0[q] / (g0[q] - g1[q]) if g0[q] > 0.0 else 0.0
                if tau < tau_best:
                    tau_best = tau
                    j = q
        # Illinois refinement of the crossing of g_j on [0, 1] (fraction of `remaining`)
        ta = 0.0
        ga = g0[j]
        tb = 1.0
        gb = g1[j]
        tau = tau_best
        side = 0
        if ga > 0.0:
            for _ in range(ILLINOIS_ITERATIONS):
                _rk_step(t, y, k1, mode, u, p, cfg, eps, tau * remaining, A, b, c, K, ytmp, ynew, ftmp)
                state_derivative(t + tau * remaining, ynew, mode, u, p, cfg, eps, ytmp, ftmp)
                event_values(t + tau * remaining, ynew, mode, ftmp, p, cfg, g1)
                gt = g1[j]
                if gt == 0.0:
                    tb = tau
                    break
                if gt > 0.0:
                    ta = tau
                    ga = gt
                    if side == 1:
                        gb *= 0.5
                    side = 1
                else:
                    tb = tau
                    gb = gt
                    if side == -1:
                        ga *= 0.5
                    side = -1
                tau = (ta * gb - tb * ga) / (gb - ga)
            tau = tb  # end just after the crossing
        else:
            tau = 0.0
        # advance to the event
        if tau > 0.0:
            _rk_step(t, y, k1, mode, u, p, cfg, eps, tau * remaining, A, b, c, K, ytmp, ynew, ftmp)
            for i in range(n):
                y[i] = ynew[i]
        t += tau * remaining
        remaining -= tau * remaining
        # switch the mode of disc j
        if mode[j] != 0:
            if j == 0:
                y[S_WU] = 0.0
            else:
                y[S_WL] = 0.0
            mode[j] = 0
        else:
            state_derivative(t, y, mode, u, p, cfg, 0.0, k1, fric)
            if j == 0:
                lo, hi = upper_stick_bounds(t, y, p)
            else:
                lo, hi = lower_stick_bounds(t, y, p, brake_on(cfg))
            mode[j] = 1 if (fric[j] - lo) >= (hi - fric[j]) else -1
        resolve_modes(t, y, mode, u, p, cfg, k1, fric)
        n_events += 1
        if remaining <= 1e-15:
            return n_events
    for i in range(n):
        y[i] = ynew[i]
        k1[i] = kend[i]
    fric[0] = fend0
    fric[1] = fend1
    return n_events


@njit(cache=True)
def run_trajectory(y, mode, U, p, cfg, dt, t0, eps, A, b, c, rec_every, out, init_modes, n_steps, hist, head,
                   cols=None):
    """Integrate one trajectory over n_steps steps (command U[i] held over step i; U may hold one
    value for a constant command).

    ``y``/``mode`` are updated in place to the final state, ``hist``/``head`` are the delay
    line.  ``out`` receives ``n_steps // rec_every + 1`` samples (none when it has no rows) of all
    output columns or of the columns ``cols`` (see ``model.record``).
    Returns the number of mode switches.
    """
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    n_u = U.shape[0]
    record_on = out.shape[0] > 0
    t = t0
    u_cmd = U[0]
    u = delay_line_step(hist, head, u_cmd, p, dt) if n_steps > 0 else delay_line_read(hist, head, u_cmd, p, dt)
    if eps > 0.0:  # smoothed friction: no stick state
        mode[0] = 2
        mode[1] = 2
        state_derivative(t, y, mode, u, p, cfg, eps, k1, fric)
    elif init_modes:
        initial_modes(t, y, u, p, cfg, mode, k1, fric)
    else:
        resolve_modes(t, y, mode, u, p, cfg, k1, fric)
    row = np.int64(0)  # not a literal: one compiled record
    if record_on:
        record(out, row, t, u_cmd, y, fric, mode, cols)
    n_switch = 0
    row = 1
    u_prev = u
    for i in range(n_steps):
        if i > 0:
            u = delay_line_step(hist, head, U[i] if n_u > 1 else U[0], p, dt)
        if u != u_prev:
            if eps > 0.0:
                state_derivative(t, y, mode, u, p, cfg, eps, k1, fric)
            else:
                resolve_modes(t, y, mode, u, p, cfg, k1, fric)
            u_prev = u
        n_switch += hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
        t = t0 + (i + 1) * dt
        if record_on and (i + 1) % rec_every == 0:
            # a sample carries the command applied from its time on (zero-order hold), as a recording does
            u_next = U[min(i + 1, n_steps - 1)] if n_u > 1 else U[0]
            record(out, row, t, u_next, y, fric, mode, cols)
            row += 1
    return n_switch


@njit(cache=True)
def run_batch_serial(Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes, n_steps, HIST, HEAD,
                     COLS=None):
    """run_trajectory over a batch: Y (B, N_STATE), MODE (B, 2), U (B, n) or (B, 1), P (B, n_par),
    OUT (B, n_rec, N_OUT), HIST (B, L) delay lines, HEAD (B,) their newest entries."""
    for k in range(Y.shape[0]):
        run_trajectory(Y[k], MODE[k], U[k], P[k], cfg, dt, T0[k], eps, A, b, c, rec_every, OUT[k], init_modes,
                       n_steps, HIST[k], HEAD[k:k + 1], COLS)


@njit(cache=True, parallel=True)
def run_batch_parallel(Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes, n_steps, HIST, HEAD,
                     COLS=None):
    """As run_batch_serial, trajectories spread over numba's threads."""
    for k in prange(Y.shape[0]):
        run_trajectory(Y[k], MODE[k], U[k], P[k], cfg, dt, T0[k], eps, A, b, c, rec_every, OUT[k], init_modes,
                       n_steps, HIST[k], HEAD[k:k + 1], COLS)


@njit(cache=True)
def advance_batch(Y, MODE, u, P, cfg, dt, n_sub, T, eps, A, b, c, FRIC, HIST, HEAD):
    """Advance every trajectory of a batch by n_sub steps of dt holding the command u[k]
    (the environments' control period).  Updates Y, MODE, T, the delay lines in place; FRIC
    (B, 2) receives the friction torques at the end (n_sub = 0: at the current state)."""
    K, ytmp, k1, ynew, _, ftmp, g0, g1 = alloc_work(b.shape[0])
    for k in range(Y.shape[0]):
        y = Y[k]
        mode = MODE[k]
        fric = FRIC[k]
        p = P[k]
        hist = HIST[k]
        head = HEAD[k:k + 1]
        t = T[k]
        ue = delay_line_step(hist, head, u[k], p, dt) if n_sub > 0 else delay_line_read(hist, head, u[k], p, dt)
        if eps > 0.0:
            mode[0] = 2
            mode[1] = 2
            state_derivative(t, y, mode, ue, p, cfg, eps, k1, fric)
        else:
            resolve_modes(t, y, mode, ue, p, cfg, k1, fric)
        for s in range(n_sub):
            if s > 0 and HAS_DELAY:
                u_new = delay_line_step(hist, head, u[k], p, dt)
                if u_new != ue:
                    ue = u_new
                    if eps > 0.0:
                        state_derivative(t, y, mode, ue, p, cfg, eps, k1, fric)
                    else:
                        resolve_modes(t, y, mode, ue, p, cfg, k1, fric)
            hybrid_step(t, y, k1, fric, mode, ue, p, cfg, eps, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
            t += dt
        T[k] = t
