"""Kernel template: adaptive embedded Runge-Kutta (Dormand-Prince 5(4)) between located events.

Steps grow and shrink with the embedded error estimate; mode switches are located with the
fixed-step event logic of :func:`drillgym.kernels.stepping.hybrid_step`, and outputs are written on
the fixed grid ``t0 + i dt``.  This template is specialised per composition of effects
(:mod:`drillgym.effects.codegen`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from drillgym.kernels.commands import command_at, delay_line_step
from drillgym.kernels.hooks import HAS_DELAY
from drillgym.kernels.model import event_values, record, resolve_modes, state_derivative
from drillgym.kernels.stepping import (
    _rk_step,
    active_states,
    alloc_work,
    copy_step_state,
    hybrid_step,
    start_trajectory,
)

__all__ = ["DP54_E", "run_batch_adaptive", "run_trajectory_adaptive"]

#: b - b_hat of Dormand-Prince 5(4) (7 stages, the 7th the derivative at the step end: FSAL)
DP54_E = np.array([71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0, -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0])


@njit(cache=True, _nrt=False)
def _dp54_error(y0, y1, K, h, rtol, atol, n):
    """Scaled error norm (max over the evolving states) of the step y0 -> y1 of size h whose stages
    (and end derivative, row 6) are in K."""
    err = 0.0
    for j in range(n):
        e = 0.0
        for i in range(7):
            e += DP54_E[i] * K[i, j]
        sc = atol + rtol * max(abs(y0[j]), abs(y1[j]))
        r = abs(h * e) / sc
        if r > err:
            err = r
    return err


@njit(cache=True, _nrt=False)
def _crossing_estimate(t, y0, k0, mode, fric0, u, p, cfg, eps, h, A, b, c, K, ytmp, ynew, ftmp, g0, g1):
    """Fraction of a step of length h from (t, y0) at which the first event function crosses zero, by
    the linear estimate of :func:`hybrid_step` on the modes held (2.0 when none crosses)."""
    _rk_step(t, y0, k0, mode, u, p, cfg, eps, h, A, b, c, K, ytmp, ynew, ftmp)
    state_derivative(t + h, ynew, mode, u, p, cfg, eps, ytmp, ftmp)
    event_values(t + h, ynew, mode, ftmp, p, cfg, g1)
    event_values(t, y0, mode, fric0, p, cfg, g0)
    tau_best = 2.0
    for q in range(2):
        if g1[q] < 0.0:
            tau = g0[q] / (g0[q] - g1[q]) if g0[q] > 0.0 else 0.0
            tau_best = min(tau_best, tau)
    return tau_best


@njit(cache=True)
def run_trajectory_adaptive(
    y,
    mode,
    U,
    p,
    cfg,
    dt,
    t0,
    eps,
    A,
    b,
    c,
    rec_every,
    out,
    init_modes,
    n_steps,
    hist,
    head,
    rtol,
    atol,
    cols=None,
    USTEP=None,
):
    """As :func:`run_trajectory` (same contract, command U[i] held over grid step i, outputs on the grid
    t0 + i dt), but integrated with adaptive Dormand-Prince 5(4) steps (A, b, c: DP5) between the
    grid points where the command changes: steps grow as long as the embedded error estimate stays
    below 1 (relative rtol, absolute atol per state).  Events are located exactly as on the fixed
    grid: a step in which a disc switches mode is redone, first up to the grid point before the
    estimated crossing (an ordinary error-controlled step) and then, from there, up to the next grid
    point (at most dt, the switch located inside it).  Outputs between step ends are cubic Hermite
    interpolants of the state (4th order) with the step's modes.  Returns the number of mode switches."""
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    ns = y.shape[0]
    n_act = active_states(cfg)
    y0 = np.empty(ns)
    k0 = np.empty(ns)
    yi = np.empty(ns)
    fr0 = np.zeros(2)
    fri = np.zeros(2)
    md0 = np.zeros(2, dtype=np.int64)
    n_u = U.shape[0]
    record_on = out.shape[0] > 0
    need_fric = cols is None
    if cols is not None:
        for j in range(cols.shape[0]):
            if cols[j] == 14 or cols[j] == 15:
                need_fric = True
    t = t0
    u, jc = start_trajectory(
        y, mode, U, p, cfg, dt, t0, eps, out, init_modes, n_steps, hist, head, cols, USTEP, k1, fric
    )
    row = np.int64(1)
    n_switch = 0
    jr = 0  # table cursor of the recorded commands (jc runs ahead, to the next change)
    g_done = 0  # grid index of the current time when on the grid (t == t0 + g_done dt), else the last passed
    h = dt
    j_end = 0
    u_pend = u
    while g_done < n_steps:
        # the next grid index at which the command the motor sees changes (or the end)
        j_end = g_done + 1
        while j_end < n_steps:
            if USTEP is None and n_u == 1 and not HAS_DELAY:
                j_end = n_steps
                break
            u_cmd, jc = command_at(U, j_end, USTEP, jc)
            v = delay_line_step(hist, head, u_cmd, p, dt)
            if v != u:
                u_pend = v
                break
            j_end += 1
        t_end = t0 + j_end * dt
        while g_done < j_end:
            t_next_grid = t0 + (g_done + 1) * dt
            hs = min(h, t_end - t)
            if t + hs > t_end - 1e-9 * dt:
                hs = t_end - t
            copy_step_state(y, k1, fric, mode, y0, k0, fr0, md0)
            nev = hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, hs, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
            if nev > 0 and hs > t_next_grid - t + 1e-9 * dt:
                # a switch inside a long step: step to the grid point before the estimated crossing ...
                copy_step_state(y0, k0, fr0, md0, y, k1, fric, mode)
                tau = _crossing_estimate(t, y0, k0, mode, fr0, u, p, cfg, eps, hs, A, b, c, K, ytmp, ynew, ftmp, g0, g1)
                g_before = np.int64(math.floor((t + min(tau, 1.0) * hs - t0) / dt + 1e-9)) - 1
                nev = 1
                if g_before > g_done + 1 and tau <= 1.0:
                    hs = t0 + g_before * dt - t
                    nev = hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, hs, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
                    if nev > 0:  # the crossing came earlier than estimated
                        copy_step_state(y0, k0, fr0, md0, y, k1, fric, mode)
                if nev > 0:  # ... and from there over the grid interval holding it (events exact there)
                    hs = t_next_grid - t
                    nev = hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, hs, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
            if nev == 0:
                err = _dp54_error(y0, y, K, hs, rtol, atol, n_act)
                if err > 1.0:
                    copy_step_state(y0, k0, fr0, md0, y, k1, fric, mode)
                    h = hs * max(0.2, 0.9 * err**-0.2)
                    continue
                h = hs * min(5.0, max(0.2, 0.9 * (err + 1e-30) ** -0.2))
                h = max(h, 1e-3 * dt)
            n_switch += nev
            t1 = t + hs
            # record the grid points passed: (t, t1]
            g = g_done + 1
            while g <= j_end and t0 + g * dt <= t1 + 1e-9 * dt:
                tg = t0 + g * dt
                if record_on and g % rec_every == 0:
                    u_next, jr = command_at(U, min(g, n_steps - 1), USTEP, jr)
                    if abs(tg - t1) <= 1e-9 * dt:
                        record(out, row, tg, u_next, y, fric, mode, cols)
                    else:  # cubic Hermite on the step (no event inside it)
                        s = (tg - t) / hs
                        h00 = (1.0 + 2.0 * s) * (1.0 - s) * (1.0 - s)
                        h10 = s * (1.0 - s) * (1.0 - s)
                        h01 = s * s * (3.0 - 2.0 * s)
                        h11 = s * s * (s - 1.0)
                        for i in range(n_act):
                            yi[i] = h00 * y0[i] + h10 * hs * k0[i] + h01 * y[i] + h11 * hs * k1[i]
                        for i in range(n_act, ns):
                            yi[i] = y[i]
                        fri[0] = fric[0]
                        fri[1] = fric[1]
                        if need_fric:
                            state_derivative(tg, yi, mode, u, p, cfg, eps, ytmp, fri)
                        record(out, row, tg, u_next, yi, fri, mode, cols)
                    row += 1
                g += 1
            g_done = g - 1
            t = t1
            if g_done == j_end:
                t = t_end
        if j_end < n_steps:  # the command changes at grid j_end
            u = u_pend
            if eps > 0.0:
                state_derivative(t, y, mode, u, p, cfg, eps, k1, fric)
            else:
                resolve_modes(t, y, mode, u, p, cfg, k1, fric)
    return n_switch


@njit(cache=True)
def run_batch_adaptive(
    Y,
    MODE,
    U,
    P,
    cfg,
    dt,
    T0,
    eps,
    A,
    b,
    c,
    rec_every,
    OUT,
    init_modes,
    n_steps,
    HIST,
    HEAD,
    rtol,
    atol,
    COLS=None,
    USTEP=None,
):
    """run_trajectory_adaptive over a batch (one after the other)."""
    for k in range(Y.shape[0]):
        run_trajectory_adaptive(
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
            rtol,
            atol,
            COLS,
            USTEP,
        )
