"""Kernel template: the right-hand side of the rig's equations on lanes (a batch as one vectorised loop).

The batch is laid out as structure-of-arrays (one row per state, one column per lane) and the
right-hand side is written branch-free so that LLVM vectorises it (AVX2/AVX-512): friction modes
become selects, and ``exp``/``log``/``sin``/``cos`` are the vectorisable versions of
:mod:`drillgym.vmath` (libm calls would block vectorisation). The diagonal-mass configurations
(upper, torsional, free_vibration) use the report's reduced equations; lateral and coupled the
four-coordinate equations with the lateral accelerations eliminated (as :mod:`drillgym.dynamics`).

The composition's effects enter through the lane variants of the hooks
(:mod:`drillgym.kernels.hooks`); their states are extra lane rows after the mechanical ones.
The kernels are compiled without numba's reference counting (``_nrt=False``): they only take row
views of arrays allocated by :func:`drillgym.kernels.lanes.lanes_run`.
"""

from __future__ import annotations

from numba import njit

from drillgym.dynamics import (
    coupled_system,
    full_accelerations,
    isotropic_lateral_forces,
    lateral_accelerations,
    reduced_accelerations,
)
from drillgym.friction import bearing_law, brake_law_simd, upper_law
from drillgym.kernels.hooks import HAS_LANE_EFFECTS, N_STATE, hk_effects_lane, hk_lag_lane, hk_states_lane
from drillgym.params import IDX
from drillgym.vmath import vsincos

__all__ = ["N_E", "copy_rows", "lane_effects", "derivative_diag", "derivative_full", "lane_derivative", "lag_exact"]

# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Ju, _km, _Tcu, _dTcu, _bu, _dbu = IDX.Ju, IDX.km, IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Jl, _kth, _Tcl, _bl = IDX.Jl, IDX.ktheta, IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e

#: rows of the effects' work array E (as drillgym.effects.hook_writers.EFFECT_ROWS): voltage at the motor,
#: extra torques, lateral forces, slip torques, friction levels
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
def lane_effects(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E):
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
def copy_rows(src, dst):
    """dst = src, row by row (a slice assignment would need numba's reference counting)."""
    for j in range(src.shape[0]):
        s = src[j]
        d = dst[j]
        for k in range(s.shape[0]):
            d[k] = s[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR, TT, tc, cfg, E):
    """Diagonal mass ((3.19), (3.20)): K[0:2] = speeds, K[2:4] = accelerations, FR = friction
    torques (a stuck disc: zero acceleration, friction = its holding torque); the effects' state
    derivatives in K[4:].  TT (B,) step start times, tc the stage's offset (s).
    Rows are taken as 1-D views first and each loop writes at most four arrays: that is what lets
    LLVM vectorise it (more written arrays exceed its runtime alias-check budget)."""
    thu_, thl_, wu_, wl_ = Y[0], Y[1], Y[2], Y[3]
    K2, K3, FR0, FR1 = K[2], K[3], FR[0], FR[1]
    Ju, km, Jl, kth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth]
    copy_rows(Y[2:4], K[0:2])  # angle rates = speeds
    if HAS_LANE_EFFECTS:
        Z = E[N_E]  # zeros: no lateral coordinates
        lane_effects(thu_, thl_, wu_, wl_, Z, Z, Z, Z, Y, 4, MU, ML, U, PT, TT, tc, cfg, brake, E)
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
def derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E):
    """All four coordinates, MODEL.md's lateral constraints plus the effects' forces
    (dynamics' formulas, Schur complement of the m I block, stuck discs as selects).
    Two loops over the lanes, each writing three arrays (one loop writing all six exceeds LLVM's
    runtime alias-check budget and runs scalar): the first solves the whole system and writes the disc
    accelerations and the lower friction torque; the second takes the disc accelerations just
    written and gives the lateral accelerations and the upper friction torque (no brake law, no
    2x2 solve)."""
    thu_, thl_, x_, y_, wu_, wl_, vx_, vy_ = Y[0], Y[1], Y[2], Y[3], Y[4], Y[5], Y[6], Y[7]
    copy_rows(Y[4:8], K[0:4])  # position rates = velocities
    Ju, km, Jl, kth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth]
    mr, mt, k_, b_, e_ = PT[_mr], PT[_mt], PT[_k], PT[_b], PT[_e]
    K4, K5, K6, K7, FR0, FR1 = K[4], K[5], K[6], K[7], FR[0], FR[1]
    lane_effects(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, 8, MU, ML, U, PT, TT, tc, cfg, brake, E)
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
def lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, K, FR, TT, tc, cfg, E):
    """The derivative of every lane: :func:`derivative_full` (lateral, coupled) or :func:`derivative_diag`."""
    if full:
        derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E)
    else:
        derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR, TT, tc, cfg, E)


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def lag_exact(S0, Yo, U, PT, TT, h, full, cfg):
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
