"""Kernel template: lane-parallel (SIMD) RK4, a batch of trajectories as one vectorised loop.

One RK4 step of B trajectories is the same arithmetic on B lanes.  This module
lays the batch out as structure-of-arrays and writes the right-hand side
branch-free, so that LLVM vectorises it (AVX2/AVX-512): friction modes become
selects, and ``exp``/``log``/``sin``/``cos`` are the vectorisable versions below
(libm calls would block vectorisation).  The diagonal-mass configurations
(upper, torsional, free_vibration) use the report's reduced equations; lateral
and coupled the four-coordinate equations with the lateral accelerations
eliminated (as :mod:`drillgym.dynamics`).

Exactness is kept by construction: every lane takes the vectorised step, then
its event functions are checked (same definitions as :mod:`drillgym.integrators`);
a lane whose step crossed an event (a slipping disc reaching zero speed, a stuck
disc's torque leaving its stick set) is rolled back and re-stepped with the
scalar event-locating ``hybrid_step``.  Events are rare (a few per stick-slip
period of thousands of steps), so the batch runs at SIMD speed.

The per-step kernels are compiled without numba's reference counting (``_nrt=False``): they
only take row views of arrays allocated by :func:`lanes_run`, and the increments/decrements of
some thirty views per call cost about a fifth of a torsional step.

The composition's effects enter through the lane variants of the hooks
(:mod:`drillgym.kernels.hooks`); their states are extra lane rows after the mechanical ones.
Used automatically by :func:`drillgym.simulate_batch` and :class:`drillgym.BatchSimulator`
for batches of 8 or more with RK4 and exact friction.  Results agree with the scalar kernel
to rounding (tested).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.dynamics import (
    FREE_VIBRATION, UPPER, S_TL, S_TU, S_VX, S_VY, S_WL, S_WU, S_X, S_Y, brake_on, coupled_system,
    full_accelerations, isotropic_lateral_forces, lateral_accelerations, lateral_free, reduced_accelerations,
)
from drillgym.friction import bearing_law, brake_law_simd, upper_law
from drillgym.kernels.hooks import (
    HAS_DELAY, HAS_LAG, HAS_LANE_EFFECTS, N_STATE, hk_bounds_l_lane, hk_bounds_u_lane, hk_delay, hk_effects_lane,
    hk_lag_lane, hk_lag_start, hk_lane_params, hk_states_lane,
)
from drillgym.kernels.model import initial_modes, record, resolve_modes
from drillgym.kernels.stepping import alloc_work, delay_line_step, hybrid_step
from drillgym.params import IDX
from drillgym.vmath import vsincos

# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Ju, _km, _Tcu, _dTcu, _bu, _dbu = IDX.Ju, IDX.km, IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Jl, _kth, _Tcl, _bl = IDX.Jl, IDX.ktheta, IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e

# lane state rows -> state vector indices: diagonal mass (theta_u, theta_l, omega_u, omega_l);
# full (theta_u, theta_l, x, y, omega_u, omega_l, vx, vy): positions first, then their velocities;
# then the effects' states (state indices 8 ...)
_EFFECT_ROWS = list(range(8, N_STATE))
ROWS_DIAG = np.array([S_TU, S_TL, S_WU, S_WL] + _EFFECT_ROWS, dtype=np.int64)
ROWS_FULL = np.array([S_TU, S_TL, S_X, S_Y, S_WU, S_WL, S_VX, S_VY] + _EFFECT_ROWS, dtype=np.int64)


#: rows of the effects' work array E (as codegen.EFFECT_ROWS): voltage at the motor, extra torques, lateral
#: forces, slip torques, friction levels
N_E = 10
_VOLT, _QU, _QL, _QS, _QX, _QY, _TFU, _TFL = 0, 1, 2, 3, 4, 5, 6, 7


@njit(inline="always", fastmath=True, error_model="numpy")
def _base_laws(wu, wl, mu, ml, brake, Tcu, dTcu, bu, dbu, Tcl, bl, Ts, Tc, ws, delta, bb):
    """Slip torques (N m) of friction.py's laws in the directions of the modes (the caller sets a stuck
    disc's to 0)."""
    awl = abs(wl)
    tfl = brake_law_simd(awl, ml, Ts, Tc, ws, delta, bb) if brake else bearing_law(awl, ml, Tcl, bl)
    return upper_law(abs(wu), mu, Tcu, dTcu, bu, dbu), tfl


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _effects(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E):
    """Into E (N_E, B): the slip torques of friction.py's laws (in the directions of the modes), then
    the composition's effects on every lane (:func:`hooks.hk_effects_lane`: the voltage at the motor,
    extra torques and lateral forces, the slip torques with the friction effects, 0 when stuck)."""
    Tcu, dTcu, bu, dbu, Tcl, bl = PT[_Tcu], PT[_dTcu], PT[_bu], PT[_dbu], PT[_Tcl], PT[_bl]
    Ts, Tc, ws, delta, bb = PT[_Ts], PT[_Tc], PT[_ws], PT[_delta], PT[_bb]
    TFU, TFL = E[_TFU], E[_TFL]
    for k in range(thu_.shape[0]):
        TFU[k], TFL[k] = _base_laws(wu_[k], wl_[k], MU[k], ML[k], brake, Tcu[k], dTcu[k], bu[k], dbu[k], Tcl[k],
                                    bl[k], Ts[k], Tc[k], ws[k], delta[k], bb[k])
    hk_effects_lane(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg,
                    1.0 if brake else 0.0, E)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _copy_rows(src, dst):
    """dst = src, row by row (a slice assignment would need numba's reference counting)."""
    for j in range(src.shape[0]):
        s = src[j]
        d = dst[j]
        for k in range(s.shape[0]):
            d[k] = s[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR, TT, tc, cfg, E):
    """Diagonal mass ((3.19), (3.20)): K[0:2] = speeds, K[2:4] = accelerations, FR = friction
    torques (a stuck disc: zero acceleration, friction = its holding torque); the effects' state
    derivatives in K[4:].  TT (B,) step start times, tc the stage's offset (s).
    Rows are taken as 1-D views first and each loop writes at most four arrays: that is what lets
    LLVM vectorise it (more written arrays exceed its runtime alias-check budget)."""
    thu_, thl_, wu_, wl_ = Y[0], Y[1], Y[2], Y[3]
    K2, K3, FR0, FR1 = K[2], K[3], FR[0], FR[1]
    Ju, km, Jl, kth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth]
    _copy_rows(Y[2:4], K[0:2])  # angle rates = speeds
    if HAS_LANE_EFFECTS:
        Z = E[N_E]  # zeros: no lateral coordinates
        _effects(thu_, thl_, wu_, wl_, Z, Z, Z, Z, Y, 4, MU, ML, U, PT, TT, tc, cfg, brake, E)
        VOLT, QU, QL, QS, TFU, TFL = E[_VOLT], E[_QU], E[_QL], E[_QS], E[_TFU], E[_TFL]
        for k in range(thu_.shape[0]):
            mu = MU[k]
            ml = ML[k]
            string = string_on * (kth[k] * (thl_[k] - thu_[k]) + QS[k])
            a_u, a_l, fu, fl = reduced_accelerations(km[k] * VOLT[k] + QU[k], string, string_on * QL[k], TFU[k],
                                                     TFL[k], Ju[k], Jl[k], mu != 0.0, ml != 0.0)
            K2[k] = a_u
            K3[k] = a_l
            FR0[k] = fu
            FR1[k] = fl
    else:  # the base model: the laws in the one loop (three passes over the lanes cost a fifth more)
        Tcu, dTcu, bu, dbu, Tcl, bl = PT[_Tcu], PT[_dTcu], PT[_bu], PT[_dbu], PT[_Tcl], PT[_bl]
        Ts, Tc, ws, delta, bb = PT[_Ts], PT[_Tc], PT[_ws], PT[_delta], PT[_bb]
        for k in range(thu_.shape[0]):
            mu = MU[k]
            ml = ML[k]
            tfu, tfl = _base_laws(wu_[k], wl_[k], mu, ml, brake, Tcu[k], dTcu[k], bu[k], dbu[k], Tcl[k], bl[k], Ts[k],
                                  Tc[k], ws[k], delta[k], bb[k])
            tfu = tfu if mu != 0.0 else 0.0
            tfl = tfl if ml != 0.0 else 0.0
            string = string_on * kth[k] * (thl_[k] - thu_[k])
            a_u, a_l, fu, fl = reduced_accelerations(km[k] * U[k], string, 0.0, tfu, tfl, Ju[k], Jl[k], mu != 0.0,
                                                     ml != 0.0)
            K2[k] = a_u
            K3[k] = a_l
            FR0[k] = fu
            FR1[k] = fl
    if N_STATE > 8:
        for k in range(thu_.shape[0]):
            hk_states_lane(k, TT[k] + tc, U[k], thu_[k], thl_[k], wu_[k], wl_[k], 0.0, 0.0, 0.0, 0.0, Y, 4, PT, cfg,
                           K)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E):
    """All four coordinates, MODEL.md's lateral constraints plus the effects' forces
    (dynamics' formulas, Schur complement of the m I block, stuck discs as selects).
    Two loops over the lanes, each writing three arrays (one loop writing all six exceeds LLVM's
    runtime alias-check budget and runs scalar): the first solves the whole system and writes the disc
    accelerations and the lower friction torque; the second takes the disc accelerations just
    written and gives the lateral accelerations and the upper friction torque (no brake law, no
    2x2 solve)."""
    thu_, thl_, x_, y_, wu_, wl_, vx_, vy_ = Y[0], Y[1], Y[2], Y[3], Y[4], Y[5], Y[6], Y[7]
    _copy_rows(Y[4:8], K[0:4])  # position rates = velocities
    Ju, km, Jl, kth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth]
    mr, mt, k_, b_, e_ = PT[_mr], PT[_mt], PT[_k], PT[_b], PT[_e]
    K4, K5, K6, K7, FR0, FR1 = K[4], K[5], K[6], K[7], FR[0], FR[1]
    _effects(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, 8, MU, ML, U, PT, TT, tc, cfg, brake, E)
    VOLT, QU, QL, QS, QX, QY, TFU, TFL = E[_VOLT], E[_QU], E[_QL], E[_QS], E[_QX], E[_QY], E[_TFU], E[_TFL]
    for k in range(thu_.shape[0]):  # loop 1 of 2: the whole system; disc accelerations, lower friction
        thu = thu_[k]
        thl = thl_[k]
        x = x_[k]
        yy = y_[k]
        W = wu_[k]
        wl = wl_[k]
        vx = vx_[k]
        vy = vy_[k]
        mu = MU[k]
        ml = ML[k]
        alpha = thl - thu
        s, c = vsincos(alpha)
        string = kth[k] * alpha + QS[k]
        Qu, Qx, Qy = isotropic_lateral_forces(x, yy, vx, vy, W, k_[k], b_[k])
        a_u, a_l, _, _, _, fl = full_accelerations(x, yy, vx, vy, W, wl, s, c, mr[k] + mt[k], e_[k] * mr[k],
                                                   Ju[k], Jl[k], km[k] * VOLT[k] + QU[k], string, QL[k], TFU[k],
                                                   TFL[k], Qu, Qx + QX[k], Qy + QY[k], mu != 0.0, ml != 0.0)
        K4[k] = a_u
        K5[k] = a_l
        FR1[k] = fl
    for k in range(thu_.shape[0]):  # loop 2 of 2: lateral accelerations, upper friction (a stuck disc's holding torque)
        thu = thu_[k]
        thl = thl_[k]
        x = x_[k]
        yy = y_[k]
        W = wu_[k]
        wl = wl_[k]
        vx = vx_[k]
        vy = vy_[k]
        mu = MU[k]
        alpha = thl - thu
        s, c = vsincos(alpha)
        string = kth[k] * alpha + QS[k]
        tfu = TFU[k]
        Qu, Qx, Qy = isotropic_lateral_forces(x, yy, vx, vy, W, k_[k], b_[k])
        m = mr[k] + mt[k]
        P = e_[k] * mr[k]
        # g0 and s01 do not depend on the lower friction torque (0.0 here); g1 is not used
        _, s01, _, g0, _, F2, F3 = coupled_system(x, yy, vx, vy, W, wl, s, c, m, P, Ju[k], Jl[k],
                                                  km[k] * VOLT[k] + QU[k], string, QL[k], tfu, 0.0, Qu, Qx + QX[k],
                                                  Qy + QY[k], mu != 0.0, ML[k] != 0.0)
        a_u = K4[k]
        a_l = K5[k]
        a_x, a_y = lateral_accelerations(x, yy, s, c, m, P, F2, F3, a_u, a_l)
        K6[k] = a_x
        K7[k] = a_y
        FR0[k] = tfu if mu != 0.0 else g0 - s01 * a_l
    if N_STATE > 8:
        for k in range(thu_.shape[0]):
            hk_states_lane(k, TT[k] + tc, U[k], thu_[k], thl_[k], wu_[k], wl_[k], x_[k], y_[k], vx_[k], vy_[k], Y, 8,
                           PT, cfg, K)


@njit(inline="always")
def _derivative(Y, MU, ML, U, PT, full, string_on, brake, K, FR, TT, tc, cfg, E):
    if full:
        _derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E)
    else:
        _derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR, TT, tc, cfg, E)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _lag_exact(S0, Yo, U, PT, TT, h, full, cfg):
    """The declared lag states (``Input.lag``) of every lane at h after the step start, exactly
    (as the scalar kernel's ``hk_lag``): rows nm + j of Yo from the start states S0."""
    nm = 8 if full else 4
    for k in range(S0.shape[1]):
        if full:
            hk_lag_lane(k, TT[k], U[k], S0[0, k], S0[1, k], S0[4, k], S0[5, k], S0[2, k], S0[3, k], S0[6, k],
                        S0[7, k], S0, nm, PT, cfg, h, Yo)
        else:
            hk_lag_lane(k, TT[k], U[k], S0[0, k], S0[1, k], S0[2, k], S0[3, k], 0.0, 0.0, 0.0, 0.0, S0, nm, PT, cfg,
                        h, Yo)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _axpy(X0, h, KX, out):
    """out = X0 + h KX, row by row."""
    for j in range(X0.shape[0]):
        x0 = X0[j]
        kx = KX[j]
        o = out[j]
        for k in range(x0.shape[0]):
            o[k] = x0[k] + h * kx[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _lanes_rk4(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W, TT, cfg, E):
    """One classical RK4 step of every lane.

    S (n, B) lane states (rows ROWS_DIAG or ROWS_FULL), updated in place; K1 (n, B) the
    derivative at the step start, replaced by the one at the end (reused by the next step);
    FR (2, B) friction torques at the end; S0 receives the start state; OK[k] = 1 when lane k's
    event functions (as ``model.event_values``) stayed positive.  W (4n, B) work space; TT (B,)
    the step's start times.
    """
    n = S.shape[0]
    B = S.shape[1]
    nm = 8 if full else 4  # mechanical rows
    hv = nm // 2  # first velocity row
    _copy_rows(S, S0)
    Y = W[0:n]
    K2 = W[n:2 * n]
    K3 = W[2 * n:3 * n]
    K4 = W[3 * n:4 * n]
    _axpy(S0, 0.5 * h, K1, Y)
    if HAS_LAG:
        _lag_exact(S0, Y, U, PT, TT, 0.5 * h, full, cfg)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K2, FR, TT, 0.5 * h, cfg, E)
    _axpy(S0, 0.5 * h, K2, Y)
    if HAS_LAG:
        _lag_exact(S0, Y, U, PT, TT, 0.5 * h, full, cfg)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K3, FR, TT, 0.5 * h, cfg, E)
    _axpy(S0, h, K3, Y)
    if HAS_LAG:
        _lag_exact(S0, Y, U, PT, TT, h, full, cfg)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K4, FR, TT, h, cfg, E)
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
        _lag_exact(S0, S, U, PT, TT, h, full, cfg)
    _derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR, TT, h, cfg, E)
    _event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, hv)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _stage_sum(S0, K1, W, coef, m, h, out):
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
def _lanes_erk(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W, TT, cfg, E, A, b,
               c):
    """One step of an explicit Runge-Kutta tableau (A, b, c; e.g. DP5) of every lane: the contract of
    :func:`_lanes_rk4`, the stages summed as the scalar kernel's general Butcher loop
    (``stepping._rk_step``).  W (s n, B): the stage state, then the stage derivatives 2..s."""
    n = S.shape[0]
    s = b.shape[0]
    _copy_rows(S, S0)
    Y = W[0:n]
    for i in range(1, s):
        _stage_sum(S0, K1, W, A[i], i, h, Y)
        if HAS_LAG:
            _lag_exact(S0, Y, U, PT, TT, c[i] * h, full, cfg)
        _derivative(Y, MU, ML, U, PT, full, string_on, brake, W[i * n:(i + 1) * n], FR, TT, c[i] * h, cfg, E)
    _stage_sum(S0, K1, W, b, s, h, S)
    if HAS_LAG:
        _lag_exact(S0, S, U, PT, TT, h, full, cfg)
    _derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR, TT, h, cfg, E)
    nm = 8 if full else 4  # mechanical rows; the velocities from row nm // 2
    _event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, nm // 2)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, hv):
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
    """(column of U holding the command of step i, table cursor): as stepping.command_at."""
    if USTEP is None:
        return (i if n_u > 1 else 0), j
    m = USTEP.shape[0]
    while j + 1 < m and USTEP[j + 1] <= i:
        j += 1
    return j, j


@njit(cache=True, _nrt=False)
def _lane_delay_step(HIST, HEAD, k, u, m):
    """:func:`stepping.delay_line_step` for lane k, its delay given in steps (``m`` = max(delay, 0) / dt,
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


@njit(cache=True, nogil=True)
def lanes_run(Y, MODE, U, P, cfg, dt, T0, rec_every, OUT, n_steps, init_modes, FRIC_OUT, HIST, HEAD, A, b, c,
              COLS=None, USTEP=None):
    """Batch run on lanes: same contract as stepping.run_batch_serial (a fixed-step tableau A, b, c:
    RK4 unrolled, others such as DP5 by the general Butcher sums; exact friction),
    plus FRIC_OUT (B, 2) final friction.  U may hold one column (constant command) or, with USTEP
    (m,), the columns of a piecewise-constant table (U[:, j] from step USTEP[j] on).  OUT is
    sample-major, (n_samples, n_columns, B) (the caller's data[k] is OUT[:, :, k]); it may have zero
    samples (no recording)."""
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
    string_on = 0.0 if cfg == UPPER else 1.0
    brake = brake_on(cfg)
    fv = cfg == FREE_VIBRATION
    n_u = U.shape[1]
    record_on = OUT.shape[0] > 0
    row0 = np.int64(0)  # not a literal: one compiled record
    for k in range(B):
        for j in range(N_STATE):
            y[j] = Y[k, j]
        for j in range(2):
            mode[j] = MODE[k, j]
        c0 = command_col(n_u, 0, USTEP, 0)[0]
        u0 = delay_line_step(HIST[k], HEAD[k:k + 1], U[k, c0], P[k], dt)
        if HAS_LAG:  # lag states not given: the first command held before the start, as the delay line
            hk_lag_start(T0[k], u0, y, P[k], cfg)
        if init_modes:
            initial_modes(T0[k], y, u0, P[k], cfg, mode, k1, fric)
        else:
            resolve_modes(T0[k], y, mode, u0, P[k], cfg, k1, fric)
        _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
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
        new_input = False
        for k in range(B):
            TT[k] = T0[k] + i * dt
            if i > 0:
                Ucur[k] = _lane_delay_step(HIST, HEAD, k, U[k, col], DM[k]) if HAS_DELAY else U[k, col]
            new_input |= Ucur[k] != Uprev[k]
        if new_input:
            # the step-start slopes at the new input, every lane at once (a lane whose input did not
            # change gets its slopes again); then a stuck disc may be released: resolve it (scalar)
            _derivative(S, MU, ML, Ucur, PT, full, string_on, brake, K1, FR, TT, 0.0, cfg, E)
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
            _lanes_rk4(S, K1, FR, MU, ML, Ucur, PT, dt, full, string_on, brake, fv, S0, OK, W, TT, cfg, E)
        else:
            _lanes_erk(S, K1, FR, MU, ML, Ucur, PT, dt, full, string_on, brake, fv, S0, OK, W, TT, cfg, E, A, b, c)
        for k in range(B):
            if OK[k] == 0:  # an event inside this step: redo it exactly on the scalar path
                y[:] = Y[k]
                for j in range(n):
                    y[rows[j]] = S0[j, k]
                mode[0] = np.int64(MU[k])
                mode[1] = np.int64(ML[k])
                t = TT[k]
                resolve_modes(t, y, mode, Ucur[k], P[k], cfg, k1, fric)
                hybrid_step(t, y, k1, fric, mode, Ucur[k], P[k], cfg, 0.0, dt, A, b, c, K, ytmp, ynew,
                            g0, g1, ftmp)
                _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
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
