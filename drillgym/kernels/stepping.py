"""Kernel template: fixed-step Runge-Kutta with exact, event-driven stick-slip (scalar path).

See :mod:`drillgym.integrators` for the method (Leine's switch model made exact with
event location inside the fixed step).  This template is specialised per composition of
effects (:mod:`drillgym.effects.codegen`); the right-hand side and switching logic come
from the specialised :mod:`drillgym.kernels.model`, the commands and the transport-delay line
from :mod:`drillgym.kernels.commands` (whose functions are importable from here too).  The
adaptive Dormand-Prince runs are in :mod:`drillgym.kernels.adaptive`.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from drillgym.dynamics import S_WL, S_WU, brake_on, lateral_free
from drillgym.kernels.commands import command_at, delay_line_read, delay_line_step
from drillgym.kernels.hooks import HAS_DELAY, HAS_LAG, N_STATE, hk_lag, hk_lag_start
from drillgym.kernels.model import (
    event_values,
    initial_modes,
    lower_stick_bounds,
    record,
    resolve_modes,
    state_derivative,
    upper_stick_bounds,
)
from drillgym.vmath import FASTMATH

__all__ = [
    "ILLINOIS_ITERATIONS",
    "MAX_EVENTS_PER_STEP",
    "active_states",
    "advance_batch",
    "alloc_work",
    "command_at",
    "copy_step_state",
    "delay_line_read",
    "delay_line_step",
    "hybrid_step",
    "run_batch_parallel",
    "run_batch_serial",
    "run_trajectory",
    "start_trajectory",
]

MAX_EVENTS_PER_STEP = 8
ILLINOIS_ITERATIONS = 6


@njit(cache=True)
def alloc_work(n_stages: int):
    """Work arrays of ``hybrid_step`` for a tableau of n_stages:
    (K stage derivatives + end derivative, ytmp, k1, ynew, fric, ftmp, g0, g1)."""
    K = np.zeros((n_stages + 1, N_STATE))
    return (
        K,
        np.zeros(N_STATE),
        np.zeros(N_STATE),
        np.zeros(N_STATE),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2),
        np.zeros(2),
    )


@njit(cache=True, _nrt=False)
def active_states(cfg):
    """Number of leading state entries that evolve: 4 (angles, speeds) unless the disc moves
    laterally or the effects carry states (then all N_STATE)."""
    if lateral_free(cfg) or N_STATE > 8:
        return N_STATE
    return 4


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
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
        if HAS_LAG:
            hk_lag(t, u, y0, p, cfg, hh, ytmp)
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k2, fric)
        for j in range(n):
            ytmp[j] = y0[j] + hh * k2[j]
        if HAS_LAG:
            hk_lag(t, u, y0, p, cfg, hh, ytmp)
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k3, fric)
        for j in range(n):
            ytmp[j] = y0[j] + h * k3[j]
        if HAS_LAG:
            hk_lag(t, u, y0, p, cfg, h, ytmp)
        state_derivative(t + h, ytmp, mode, u, p, cfg, eps, k4, fric)
        h6 = h / 6.0
        for j in range(n):
            y_out[j] = y0[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
        if HAS_LAG:
            hk_lag(t, u, y0, p, cfg, h, y_out)
        return
    for j in range(n):
        K[0, j] = k1[j]
    for i in range(1, s):
        for j in range(n):
            acc = 0.0
            for m in range(i):
                acc += A[i, m] * K[m, j]
            ytmp[j] = y0[j] + h * acc
        if HAS_LAG:
            hk_lag(t, u, y0, p, cfg, c[i] * h, ytmp)
        state_derivative(t + c[i] * h, ytmp, mode, u, p, cfg, eps, K[i], fric)
    for j in range(n):
        acc = 0.0
        for i in range(s):
            acc += b[i] * K[i, j]
        y_out[j] = y0[j] + h * acc
    if HAS_LAG:
        hk_lag(t, u, y0, p, cfg, h, y_out)


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


@njit(inline="always")
def copy_step_state(y, k1, fric, mode, y_to, k1_to, fric_to, mode_to):
    """Copy what :func:`hybrid_step` carries between steps (state, derivative, friction, modes)."""
    for i in range(y.shape[0]):
        y_to[i] = y[i]
        k1_to[i] = k1[i]
    fric_to[0] = fric[0]
    fric_to[1] = fric[1]
    mode_to[0] = mode[0]
    mode_to[1] = mode[1]


@njit(inline="always")
def start_trajectory(y, mode, U, p, cfg, dt, t0, eps, out, init_modes, n_steps, hist, head, cols, USTEP, k1, fric):
    """The first command (through the delay line), the initial modes and the first output sample of a
    run: the start shared by the fixed-step and the adaptive integrators.  Returns (u, table cursor)."""
    u_cmd, jc = command_at(U, 0, USTEP, 0)
    u = delay_line_step(hist, head, u_cmd, p, dt) if n_steps > 0 else delay_line_read(hist, head, u_cmd, p, dt)
    if HAS_LAG:  # lag states not given: the first command held before the start, as the delay line
        hk_lag_start(t0, u, y, p, cfg)
    if eps > 0.0:  # smoothed friction: no stick state
        mode[0] = 2
        mode[1] = 2
        state_derivative(t0, y, mode, u, p, cfg, eps, k1, fric)
    elif init_modes:
        initial_modes(t0, y, u, p, cfg, mode, k1, fric)
    else:
        resolve_modes(t0, y, mode, u, p, cfg, k1, fric)
    if out.shape[0] > 0:
        record(out, np.int64(0), t0, u_cmd, y, fric, mode, cols)
    return u, jc


@njit(cache=True)
def run_trajectory(
    y, mode, U, p, cfg, dt, t0, eps, A, b, c, rec_every, out, init_modes, n_steps, hist, head, cols=None, USTEP=None
):
    """Integrate one trajectory over n_steps steps (command U[i] held over step i; U may hold one
    value for a constant command).

    ``y``/``mode`` are updated in place to the final state, ``hist``/``head`` are the delay
    line.  ``out`` receives ``n_steps // rec_every + 1`` samples (none when it has no rows) of all
    output columns or of the columns ``cols`` (see ``model.record``).  With ``USTEP`` (m,), U (m,) is a
    piecewise-constant table: U[j] from step USTEP[j] on (see :func:`command_at`).
    Returns the number of mode switches.
    """
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    record_on = out.shape[0] > 0
    t = t0
    u, jc = start_trajectory(
        y, mode, U, p, cfg, dt, t0, eps, out, init_modes, n_steps, hist, head, cols, USTEP, k1, fric
    )
    n_switch = 0
    row = np.int64(1)  # not a literal: one compiled record
    u_prev = u
    for i in range(n_steps):
        if i > 0:
            u_cmd, jc = command_at(U, i, USTEP, jc)
            u = delay_line_step(hist, head, u_cmd, p, dt)
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
            u_next = command_at(U, min(i + 1, n_steps - 1), USTEP, jc)[0]
            record(out, row, t, u_next, y, fric, mode, cols)
            row += 1
    return n_switch


@njit(cache=True)
def run_batch_serial(
    Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes, n_steps, HIST, HEAD, COLS=None, USTEP=None
):
    """run_trajectory over a batch: Y (B, N_STATE), MODE (B, 2), U (B, n) or (B, 1), P (B, n_par),
    OUT (B, n_rec, N_OUT), HIST (B, L) delay lines, HEAD (B,) their newest entries; with USTEP (m,),
    U (B, m) is a piecewise-constant table (see :func:`command_at`)."""
    for k in range(Y.shape[0]):
        run_trajectory(
            Y[k],
            MODE[k],
            U[k],
            P[k],
            cfg,
            dt,
            T0[k],
            eps,
            A,
            b,
            c,
            rec_every,
            OUT[k],
            init_modes,
            n_steps,
            HIST[k],
            HEAD[k : k + 1],
            COLS,
            USTEP,
        )


@njit(cache=True, parallel=True)
def run_batch_parallel(
    Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes, n_steps, HIST, HEAD, COLS=None, USTEP=None
):
    """As run_batch_serial, trajectories spread over numba's threads."""
    for k in prange(Y.shape[0]):
        run_trajectory(
            Y[k],
            MODE[k],
            U[k],
            P[k],
            cfg,
            dt,
            T0[k],
            eps,
            A,
            b,
            c,
            rec_every,
            OUT[k],
            init_modes,
            n_steps,
            HIST[k],
            HEAD[k : k + 1],
            COLS,
            USTEP,
        )


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
        head = HEAD[k : k + 1]
        t = T[k]
        ue = delay_line_step(hist, head, u[k], p, dt) if n_sub > 0 else delay_line_read(hist, head, u[k], p, dt)
        if HAS_LAG and n_sub > 0:  # the first step after a reset: lag states at the first command held
            hk_lag_start(t, ue, y, p, cfg)  # before the start (as the delay line, which a 0-step read leaves)
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
