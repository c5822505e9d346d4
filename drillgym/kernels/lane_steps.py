"""Kernel template: one integration step of every lane, and the check of its events.

Every lane takes the vectorised step (classical RK4 unrolled, or any explicit tableau such as DP5
by the general Butcher sums), then its event functions are checked (the definitions of
:mod:`drillgym.integrators`): a lane whose step crossed an event (a slipping disc reaching zero
speed, a stuck disc's torque leaving its stick set) is flagged, and
:func:`drillgym.kernels.lanes.lanes_run` re-steps it on the scalar event-locating path.
"""

from __future__ import annotations

from numba import njit

from drillgym.kernels.hooks import HAS_LAG, hk_bounds_l_lane, hk_bounds_u_lane
from drillgym.kernels.lane_rhs import copy_rows, lag_exact, lane_derivative
from drillgym.params import IDX

__all__ = ["axpy", "lanes_rk4", "stage_sum", "lanes_erk", "event_check"]

# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Tcu, _dTcu, _Ts, _Tcl = IDX.Tcu, IDX.dTcu, IDX.Ts, IDX.Tcl


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def axpy(X0, h, KX, out):
    """out = X0 + h KX, row by row."""
    for j in range(X0.shape[0]):
        x0 = X0[j]
        kx = KX[j]
        o = out[j]
        for k in range(x0.shape[0]):
            o[k] = x0[k] + h * kx[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def lanes_rk4(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W, TT, cfg, E):
    """One classical RK4 step of every lane.

    Parameters
    ----------
    S : numpy.ndarray
        Lane states ``(n, B)`` (rows ``ROWS_DIAG`` or ``ROWS_FULL`` of :mod:`drillgym.kernels.lanes`),
        advanced in place.
    K1 : numpy.ndarray
        The derivative ``(n, B)`` at the step start, replaced by the one at the end (reused by the
        next step).
    FR : numpy.ndarray
        Receives the friction torques ``(2, B)`` at the step end (N m).
    MU, ML : numpy.ndarray
        Friction modes of the upper and lower disc ``(B,)`` (0 stuck, +-1 slipping).
    U : numpy.ndarray
        Voltage of each lane over the step ``(B,)`` (V).
    PT : numpy.ndarray
        Lane parameter matrix ``(n_params + n_switches, B)``.
    h : float
        Step (s).
    full : bool
        Four coordinates (lateral, coupled), else the diagonal-mass equations.
    string_on : float
        1.0 when the string couples the discs, 0.0 for the upper disc alone.
    brake : bool
        The lower disc runs the brake's law.
    free_vibration : bool
        The upper disc is held.
    S0 : numpy.ndarray
        Receives the start state ``(n, B)``.
    OK : numpy.ndarray
        Receives 1 for each lane whose event functions (as ``model.event_values``) stayed
        positive, else 0.
    W : numpy.ndarray
        Work space ``(4 n, B)``.
    TT : numpy.ndarray
        The step's start time of each lane (s).
    cfg : int
        Configuration code.
    E : numpy.ndarray
        The effects' work rows ``(N_E + 1, B)``.
    """
    n = S.shape[0]
    B = S.shape[1]
    nm = 8 if full else 4  # mechanical rows
    hv = nm // 2  # first velocity row
    copy_rows(S, S0)
    Y = W[0:n]
    K2 = W[n:2 * n]
    K3 = W[2 * n:3 * n]
    K4 = W[3 * n:4 * n]
    axpy(S0, 0.5 * h, K1, Y)
    if HAS_LAG:
        lag_exact(S0, Y, U, PT, TT, 0.5 * h, full, cfg)
    lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, K2, FR, TT, 0.5 * h, cfg, E)
    axpy(S0, 0.5 * h, K2, Y)
    if HAS_LAG:
        lag_exact(S0, Y, U, PT, TT, 0.5 * h, full, cfg)
    lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, K3, FR, TT, 0.5 * h, cfg, E)
    axpy(S0, h, K3, Y)
    if HAS_LAG:
        lag_exact(S0, Y, U, PT, TT, h, full, cfg)
    lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, K4, FR, TT, h, cfg, E)
    h6 = h / 6.0
    for j in range(n):
        s = S[j]
        s0 = S0[j]
        a = K1[j]
        b = K2[j]
        c = K3[j]
        d = K4[j]
        for k in range(B):
            s[k] = s0[k] + h6 * (a[k] + 2.0 * (b[k] + c[k]) + d[k])
    if HAS_LAG:
        lag_exact(S0, S, U, PT, TT, h, full, cfg)
    lane_derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR, TT, h, cfg, E)
    event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, hv)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def stage_sum(S0, K1, W, coef, m, h, out):
    """out = S0 + h (coef[0] K1 + coef[1] K_2 + ... + coef[m-1] K_m), row by row over the lanes (the
    stage derivatives K_2.. in W's blocks 1..; the sum in the scalar kernel's order)."""
    n = S0.shape[0]
    for j in range(n):
        o = out[j]
        for k in range(o.shape[0]):
            o[k] = 0.0
        for q in range(m):
            a = coef[q]
            kq = K1[j] if q == 0 else W[q * n + j]
            for k in range(o.shape[0]):
                o[k] += a * kq[k]
        s0 = S0[j]
        for k in range(o.shape[0]):
            o[k] = s0[k] + h * o[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def lanes_erk(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W, TT, cfg, E, A, b,
               c):
    """One step of an explicit Runge-Kutta tableau (e.g. DP5) of every lane.

    The contract of :func:`lanes_rk4`, the stages summed as the scalar kernel's general Butcher
    loop. ``W`` is ``(s n, B)``: the stage state, then the stage derivatives 2..s; ``A``, ``b``,
    ``c`` are the tableau.
    """
    n = S.shape[0]
    s = b.shape[0]
    copy_rows(S, S0)
    Y = W[0:n]
    for i in range(1, s):
        stage_sum(S0, K1, W, A[i], i, h, Y)
        if HAS_LAG:
            lag_exact(S0, Y, U, PT, TT, c[i] * h, full, cfg)
        lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, W[i * n:(i + 1) * n], FR, TT, c[i] * h, cfg, E)
    stage_sum(S0, K1, W, b, s, h, S)
    if HAS_LAG:
        lag_exact(S0, S, U, PT, TT, h, full, cfg)
    lane_derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR, TT, h, cfg, E)
    nm = 8 if full else 4  # mechanical rows; the velocities from row nm // 2
    event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, nm // 2)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, hv):
    """OK[k] = 1 when lane k's event functions at the step end stayed positive (slipping discs kept
    their direction, stuck discs' holding torques stayed in their stick sets)."""
    bf = 1.0 if brake else 0.0
    thu_, thl_, wu_, wl_ = S[0], S[1], S[hv], S[hv + 1]
    Tcu, dTcu, Ts, Tcl = PT[_Tcu], PT[_dTcu], PT[_Ts], PT[_Tcl]
    FR0, FR1 = FR[0], FR[1]
    for k in range(S.shape[1]):
        t = TT[k] + h
        thu = thu_[k]
        thl = thl_[k]
        wu = wu_[k]
        wl = wl_[k]
        x = S[2, k] if full else 0.0
        yy = S[3, k] if full else 0.0
        vx = S[6, k] if full else 0.0
        vy = S[7, k] if full else 0.0
        fu = FR0[k]
        fl = FR1[k]
        mu = MU[k]
        ml = ML[k]
        # both branches computed, then selected: branch-free, so the loop vectorises
        lo_u, hi_u = hk_bounds_u_lane(-Tcu[k] + dTcu[k], Tcu[k] + dTcu[k], k, t, thu, thl, wu, wl, x, yy, vx, vy, S,
                                      nm, PT, 0.0)
        gu = mu * wu if mu != 0.0 else min(hi_u - fu, fu - lo_u)
        gu = 1.0 if free_vibration else gu
        lim = Ts[k] if brake else Tcl[k]
        lo_l, hi_l = hk_bounds_l_lane(-lim, lim, k, t, thu, thl, wu, wl, x, yy, vx, vy, S, nm, PT, bf)
        gl = ml * wl if ml != 0.0 else min(hi_l - fl, fl - lo_l)
        gl = gl if string_on > 0.0 else 1.0
        OK[k] = 1 if (gu >= 0.0 and gl >= 0.0) else 0
