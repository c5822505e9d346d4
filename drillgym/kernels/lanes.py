"""Kernel template: lane-parallel (SIMD) runs, a batch of trajectories as one vectorised loop.

One step of B trajectories is the same arithmetic on B lanes: :func:`lanes_run` lays the batch out
as structure-of-arrays, steps every lane with :mod:`drillgym.kernels.lane_steps` (which holds the
right-hand side on lanes too) and records the samples column by column over the lanes.

Exactness is kept by construction: a lane whose step crossed an event is rolled back and
re-stepped with the scalar event-locating ``hybrid_step``. Events are rare (a few per stick-slip
period of thousands of steps), so the batch runs at SIMD speed.

The per-step kernels are compiled without numba's reference counting (``_nrt=False``): they only
take row views of arrays allocated by :func:`lanes_run`, and the increments and decrements of some
thirty views per call cost about a fifth of a torsional step.

Used by :func:`drillgym.simulate_batch` and :class:`drillgym.BatchSimulator` for batches of 8 or
more with a fixed-step method and exact friction. Results agree with the scalar kernel to rounding
(tested).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.dynamics import (
    FREE_VIBRATION,
    S_TL,
    S_TU,
    S_VX,
    S_VY,
    S_WL,
    S_WU,
    S_X,
    S_Y,
    UPPER,
    brake_on,
    lateral_free,
)
from drillgym.kernels.commands import delay_line_step
from drillgym.kernels.hooks import HAS_DELAY, HAS_LAG, N_STATE, hk_delay, hk_lag_start, hk_lane_params
from drillgym.kernels.lane_steps import N_E, lane_derivative, lanes_erk, lanes_rk4
from drillgym.kernels.model import initial_modes, record, resolve_modes
from drillgym.kernels.stepping import alloc_work, hybrid_step

__all__ = ["ROWS_DIAG", "ROWS_FULL", "command_col", "lane_start", "lanes_commands", "lanes_step", "lanes_run"]

# lane state rows -> state vector indices: diagonal mass (theta_u, theta_l, omega_u, omega_l);
# full (theta_u, theta_l, x, y, omega_u, omega_l, vx, vy): positions first, then their velocities;
# then the effects' states (state indices 8 ...)
_EFFECT_ROWS = list(range(8, N_STATE))
ROWS_DIAG = np.array([S_TU, S_TL, S_WU, S_WL] + _EFFECT_ROWS, dtype=np.int64)
ROWS_FULL = np.array([S_TU, S_TL, S_X, S_Y, S_WU, S_WL, S_VX, S_VY] + _EFFECT_ROWS, dtype=np.int64)


@njit(cache=True)
def _lane_to_state(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode):
    """Copy lane k into the scalar kernel's state/derivative/friction/mode (y's other entries kept)."""
    for j in range(rows.shape[0]):
        y[rows[j]] = S[j, k]
        k1[rows[j]] = K1[j, k]
    fric[0] = FR[0, k]
    fric[1] = FR[1, k]
    mode[0] = np.int64(MU[k])
    mode[1] = np.int64(ML[k])


@njit(cache=True)
def _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode):
    """Copy the scalar kernel's state/derivative/friction/mode into lane k (the inverse of :func:`_lane_to_state`)."""
    for j in range(rows.shape[0]):
        S[j, k] = y[rows[j]]
        K1[j, k] = k1[rows[j]]
    FR[0, k] = fric[0]
    FR[1, k] = fric[1]
    MU[k] = float(mode[0])
    ML[k] = float(mode[1])


@njit(cache=True, _nrt=False)
def _record_lanes(OUT, row, T0, tt, U, ucol, S, FR, MU, ML, inv, Y, COLS, XW, YW):
    """One output sample of every lane straight from the lane rows (as ``model.record`` of the lane's
    state, column by column over the lanes: no per-lane copies).  OUT is sample-major, (n_samples,
    n_columns, B): a column of a sample is one contiguous store over the lanes.  inv[i] = lane row of
    state i, or -1 (a state that does not evolve: read from Y); tt the sample's time since T0 (s)."""
    B = S.shape[1]
    nc = OUT.shape[1]
    lateral = False
    for jj in range(nc):
        c = COLS[jj] if COLS is not None else jj
        if 11 <= c <= 13:
            lateral = True
    if lateral:  # fixed-frame position (m) once for the three columns; no trigonometry at the centre
        for k in range(B):
            x = S[inv[4], k] if inv[4] >= 0 else Y[k, 4]
            yy = S[inv[5], k] if inv[5] >= 0 else Y[k, 5]
            if x == 0.0 and yy == 0.0:
                XW[k] = 0.0
                YW[k] = 0.0
            else:
                thu = S[inv[0], k]
                ct = np.cos(thu)
                st = np.sin(thu)
                XW[k] = x * ct - yy * st
                YW[k] = x * st + yy * ct
    for jj in range(nc):
        c = COLS[jj] if COLS is not None else jj
        if c == 0:
            for k in range(B):
                OUT[row, jj, k] = T0[k] + tt
        elif c == 1:
            for k in range(B):
                OUT[row, jj, k] = U[k, ucol]
        elif c == 10:
            a = S[inv[1]]
            b = S[inv[0]]
            for k in range(B):
                OUT[row, jj, k] = a[k] - b[k]
        elif c == 11:
            for k in range(B):
                OUT[row, jj, k] = XW[k]
        elif c == 12:
            for k in range(B):
                OUT[row, jj, k] = YW[k]
        elif c == 13:
            for k in range(B):
                OUT[row, jj, k] = np.sqrt(XW[k] * XW[k] + YW[k] * YW[k])
        elif c == 14 or c == 15:
            f = FR[c - 14]
            for k in range(B):
                OUT[row, jj, k] = f[k]
        elif c == 16 or c == 17:
            m = MU if c == 16 else ML
            for k in range(B):
                OUT[row, jj, k] = 1.0 if m[k] == 0.0 else 0.0
        else:
            si = c - 2 if c < 10 else c - 10
            r = inv[si]
            if r >= 0:
                src = S[r]
                for k in range(B):
                    OUT[row, jj, k] = src[k]
            else:
                for k in range(B):
                    OUT[row, jj, k] = Y[k, si]


@njit(inline="always")
def command_col(n_u, i, USTEP, j):
    """The column of U holding the command of step ``i``, and the table cursor (as ``commands.command_at``).

    Parameters
    ----------
    n_u : int
        Columns of U.
    i : int
        The step.
    USTEP : numpy.ndarray or None
        First step of each entry of a command table; None when U is not a table.
    j : int
        The table cursor of the previous call (0 at the start).

    Returns
    -------
    tuple of (int, int)
        The column and the new cursor.
    """
    if USTEP is None:
        return (i if n_u > 1 else 0), j
    m = USTEP.shape[0]
    while j + 1 < m and USTEP[j + 1] <= i:
        j += 1
    return j, j


@njit(cache=True, _nrt=False)
def _lane_delay_step(HIST, HEAD, k, u, m):
    """:func:`commands.delay_line_step` for lane k, its delay given in steps (``m`` = max(delay, 0) / dt,
    worked out once per run, as that function does at every step): the same arithmetic on the lane's rows
    in place (row views taken per lane and step cost numba's reference counting: a fifth of a step of
    the coupled model)."""
    L = HIST.shape[1]
    h = HEAD[k]
    if h < 0:
        for i in range(L):
            HIST[k, i] = u
        h = 0
    else:
        h += 1
        if h >= L:
            h = 0
        HIST[k, h] = u
    HEAD[k] = h
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
    return (1.0 - f) * HIST[k, i0] + f * HIST[k, i1]


@njit(cache=True)
def lane_start(t, y, mode, u0, p, cfg, init_modes, S, K1, FR, MU, ML, rows, k, k1, fric):
    """Lane k of S started at time t (s) from the state y with the command u0 (V) entering the Input chain: a lag
    state at u0 (the command held before the start, as the delay line), the modes found (``init_modes``) or
    resolved from ``mode``; k1, fric its step-start slopes and friction."""
    if HAS_LAG:
        hk_lag_start(t, u0, y, p, cfg)
    if init_modes:
        initial_modes(t, y, u0, p, cfg, mode, k1, fric)
    else:
        resolve_modes(t, y, mode, u0, p, cfg, k1, fric)
    _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)


@njit(cache=True)
def lanes_commands(i, dt, T0, U, col, HIST, HEAD, DM, Ucur, Uprev, TT):
    """The step i's times TT = T0 + i dt (s) and commands Ucur (V) of the lanes: column ``col`` of U through the
    delay lines (DM their delays in steps; step 0 keeps Ucur); True when a lane's differs from Uprev."""
    new_input = False
    for k in range(Ucur.shape[0]):
        TT[k] = T0[k] + i * dt
        if i > 0:
            Ucur[k] = _lane_delay_step(HIST, HEAD, k, U[k, col], DM[k]) if HAS_DELAY else U[k, col]
        new_input |= Ucur[k] != Uprev[k]
    return new_input


@njit(cache=True)
def lanes_step(new_input, Y, P, PT, cfg, dt, A, b, c, rows, S, S0, K1, FR, MU, ML, OK, W, E, Ucur, Uprev, TT,
               y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1):  # fmt: skip
    """One integration step (dt, s) of the B lanes S at the commands Ucur (V) from the times TT (s).

    With ``new_input`` (a lane's command differs from Uprev) the step-start slopes are taken again at the new
    commands, every lane at once, and a stuck disc whose command changed is resolved on the scalar path; then the
    lanes step (RK4 unrolled, or the tableau A, b, c) and a lane with an event inside the step (OK 0) is stepped
    again exactly on the scalar path from its start S0.  Y (B, N_STATE) the lanes' full states (lateral and effect
    states outside S), P and PT the parameter rows and their transposed lane rows; the rest are work arrays
    (:func:`lanes_run` allocates them).
    """
    B = S.shape[1]
    n = rows.shape[0]
    full = lateral_free(cfg)
    string_on = 0.0 if cfg == UPPER else 1.0
    brake = brake_on(cfg)
    fv = cfg == FREE_VIBRATION
    if new_input:
        # the step-start slopes at the new input, every lane at once (a lane whose input did not
        # change gets its slopes again); then a stuck disc may be released: resolve it (scalar)
        lane_derivative(S, MU, ML, Ucur, PT, full, string_on, brake, K1, FR, TT, 0.0, cfg, E)
        for k in range(B):
            if Ucur[k] == Uprev[k]:
                continue
            Uprev[k] = Ucur[k]
            if (MU[k] == 0.0 and not fv) or (ML[k] == 0.0 and cfg != UPPER):
                y[:] = Y[k]
                _lane_to_state(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
                resolve_modes(TT[k], y, mode, Ucur[k], P[k], cfg, k1, fric)
                _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
    if b.shape[0] == 4:  # classical RK4 (the only 4-stage tableau), unrolled
        lanes_rk4(S, K1, FR, MU, ML, Ucur, PT, dt, full, string_on, brake, fv, S0, OK, W, TT, cfg, E)
    else:
        lanes_erk(S, K1, FR, MU, ML, Ucur, PT, dt, full, string_on, brake, fv, S0, OK, W, TT, cfg, E, A, b, c)
    for k in range(B):
        if OK[k] == 0:  # an event inside this step: redo it exactly on the scalar path
            y[:] = Y[k]
            for j in range(n):
                y[rows[j]] = S0[j, k]
            mode[0] = np.int64(MU[k])
            mode[1] = np.int64(ML[k])
            t = TT[k]
            resolve_modes(t, y, mode, Ucur[k], P[k], cfg, k1, fric)
            hybrid_step(t, y, k1, fric, mode, Ucur[k], P[k], cfg, 0.0, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
            _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)


@njit(cache=True, nogil=True)
def lanes_run(
    Y,
    MODE,
    U,
    P,
    cfg,
    dt,
    T0,
    rec_every,
    OUT,
    n_steps,
    init_modes,
    FRIC_OUT,
    HIST,
    HEAD,
    A,
    b,
    c,
    COLS=None,
    USTEP=None,
):
    """Run a batch on lanes, with exact friction and a fixed-step tableau.

    The contract of ``stepping.run_batch_serial``, plus the final friction torques. Classical RK4
    is unrolled; other tableaus (e.g. DP5) run by the general Butcher sums.

    Parameters
    ----------
    Y : numpy.ndarray
        States ``(B, n_state)``, advanced in place.
    MODE : numpy.ndarray
        Friction modes ``(B, 2)`` (0 stuck, +-1 slipping), updated in place.
    U : numpy.ndarray
        Commands (V), ``(B, 1)`` for a constant, ``(B, n_steps)`` per step, or with ``USTEP`` the
        ``m`` entries of a piecewise-constant table (``U[:, j]`` from step ``USTEP[j]`` on).
    P : numpy.ndarray
        Parameter matrix ``(B, n_params)``.
    cfg : int
        Configuration code.
    dt : float
        Integration step (s).
    T0 : numpy.ndarray
        Start time of each run (s).
    rec_every : int
        Record every k-th step.
    OUT : numpy.ndarray
        Sample-major output ``(n_samples, n_columns, B)`` (a run's samples are ``OUT[:, :, k]``);
        zero samples records nothing.
    n_steps : int
        Steps to run.
    init_modes : bool
        Start from the modes the initial states imply (else resolve ``MODE`` as given).
    FRIC_OUT : numpy.ndarray
        Receives the final friction torques ``(B, 2)`` (N m).
    HIST, HEAD : numpy.ndarray
        Delay lines ``(B, L)`` and their heads ``(B,)``, updated in place.
    A, b, c : numpy.ndarray
        The fixed-step Butcher tableau.
    COLS : numpy.ndarray, optional
        Indices of the recorded columns; None records all.
    USTEP : numpy.ndarray, optional
        First step of each entry of a command table.
    """
    B = Y.shape[0]
    full = lateral_free(cfg)
    rows = ROWS_FULL if full else ROWS_DIAG
    n = rows.shape[0]
    XW = np.zeros(B)  # recording work space: fixed-frame lateral position
    YW = np.zeros(B)
    inv = np.full(N_STATE, -1, dtype=np.int64)  # state index -> lane row
    for j in range(n):
        inv[rows[j]] = j
    PT = hk_lane_params(P)  # parameter rows, then the effects' switches
    S = np.empty((n, B))
    S0 = np.empty((n, B))
    K1 = np.zeros((n, B))
    FR = np.zeros((2, B))
    MU = np.zeros(B)
    ML = np.zeros(B)
    OK = np.zeros(B, dtype=np.int64)
    W = np.zeros((max(4, b.shape[0]) * n, B))
    E = np.zeros((N_E + 1, B))  # the effects' work rows, then a row of zeros
    Ucur = np.empty(B)
    Uprev = np.empty(B)
    TT = np.empty(B)
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    y = np.zeros(N_STATE)
    mode = np.zeros(2, dtype=np.int64)
    n_u = U.shape[1]
    record_on = OUT.shape[0] > 0
    row0 = np.int64(0)  # not a literal: one compiled record
    for k in range(B):
        for j in range(N_STATE):
            y[j] = Y[k, j]
        for j in range(2):
            mode[j] = MODE[k, j]
        c0 = command_col(n_u, 0, USTEP, 0)[0]
        u0 = delay_line_step(HIST[k], HEAD[k : k + 1], U[k, c0], P[k], dt)
        lane_start(T0[k], y, mode, u0, P[k], cfg, init_modes, S, K1, FR, MU, ML, rows, k, k1, fric)
        for j in range(N_STATE):
            Y[k, j] = y[j]
        if record_on:
            record(OUT[:, :, k], row0, T0[k], U[k, c0], y, fric, mode, COLS)
        Uprev[k] = u0
        Ucur[k] = u0
    DM = np.zeros(B)  # each lane's delay in steps (a Delay effect)
    if HAS_DELAY:
        for k in range(B):
            DM[k] = max(hk_delay(P[k]), 0.0) / dt
    jc = 0
    for i in range(n_steps):
        col, jc = command_col(n_u, i, USTEP, jc)
        new_input = lanes_commands(i, dt, T0, U, col, HIST, HEAD, DM, Ucur, Uprev, TT)
        lanes_step(new_input, Y, P, PT, cfg, dt, A, b, c, rows, S, S0, K1, FR, MU, ML, OK, W, E, Ucur, Uprev, TT,
                   y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1)  # fmt: skip
        if record_on and (i + 1) % rec_every == 0:
            row = (i + 1) // rec_every
            ncol = command_col(n_u, min(i + 1, n_steps - 1), USTEP, jc)[0]
            _record_lanes(OUT, row, T0, (i + 1) * dt, U, ncol, S, FR, MU, ML, inv, Y, COLS, XW, YW)
    for k in range(B):
        for j in range(n):
            Y[k, rows[j]] = S[j, k]
        MODE[k, 0] = np.int64(MU[k])
        MODE[k, 1] = np.int64(ML[k])
        FRIC_OUT[k, 0] = FR[0, k]
        FRIC_OUT[k, 1] = FR[1, k]
