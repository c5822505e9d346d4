"""Kernel template: the rig's right-hand side on lanes, one integration step of every lane, and its event check.

A batch of trajectories runs as one vectorised loop. The batch is laid out as structure-of-arrays
(one row per state, one column per lane) and the right-hand side is written branch-free so that
LLVM vectorises it (AVX2/AVX-512): friction modes become selects, and ``exp``/``log``/``sin``/``cos``
are the vectorisable versions of :mod:`drillgym.vmath` (libm calls would block vectorisation). The
diagonal-mass configurations (upper, torsional, free_vibration) use the report's reduced equations;
lateral and coupled the four-coordinate equations with the lateral accelerations eliminated (as
:mod:`drillgym.dynamics`).

Every lane takes the vectorised step (classical RK4 unrolled, or any explicit tableau such as DP5
by the general Butcher sums), then its event functions are checked (the definitions of
:mod:`drillgym.integrators`): a lane whose step crossed an event (a slipping disc reaching zero
speed, a stuck disc's torque leaving its stick set) is flagged, and
:func:`drillgym.kernels.lanes.lanes_run` re-steps it on the scalar event-locating path.

The composition's effects enter through the lane variants of the hooks
(:mod:`drillgym.kernels.hooks`); their states are extra lane rows after the mechanical ones. The
kernels are compiled without numba's reference counting (``_nrt=False``): they only take row views
of arrays allocated by :func:`drillgym.kernels.lanes.lanes_run`.

Compiled with :data:`drillgym.vmath.FASTMATH` (flags that change no finite value), so a step gives the
same bits however LLVM inlined it: in the lane kernel, the closed loop, or beside callees loaded from
numba's cache.
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
from drillgym.kernels.hooks import (
    HAS_LAG,
    HAS_LANE_EFFECTS,
    N_STATE,
    hk_bounds_l_lane,
    hk_bounds_u_lane,
    hk_effects_lane,
    hk_lag_lane,
    hk_states_lane,
)
from drillgym.params import IDX
from drillgym.vmath import FASTMATH, vsincos

__all__ = [
    "N_E",
    "copy_rows",
    "lane_effects",
    "derivative_diag",
    "derivative_full",
    "lane_derivative",
    "lag_exact",
    "axpy",
    "lanes_rk4",
    "stage_sum",
    "lanes_erk",
    "event_check",
]

# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Ju, _km, _Tcu, _dTcu, _bu, _dbu = IDX.Ju, IDX.km, IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Jl, _kth, _Tcl, _bl = IDX.Jl, IDX.ktheta, IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e

#: rows of the effects' work array E (as drillgym.effects.hook_writers.EFFECT_ROWS): voltage at the motor,
#: extra torques, lateral forces, slip torques, friction levels
N_E = 10
_VOLT, _QU, _QL, _QS, _QX, _QY, _TFU, _TFL = 0, 1, 2, 3, 4, 5, 6, 7


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _base_laws(wu, wl, mu, ml, brake, Tcu, dTcu, bu, dbu, Tcl, bl, Ts, Tc, ws, delta, bb):
    """Slip torques (N m) of friction.py's laws in the directions of the modes (the caller sets a stuck
    disc's to 0)."""
    awl = abs(wl)
    tfl = brake_law_simd(awl, ml, Ts, Tc, ws, delta, bb) if brake else bearing_law(awl, ml, Tcl, bl)
    return upper_law(abs(wu), mu, Tcu, dTcu, bu, dbu), tfl


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def lane_effects(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E):
    """Into E (N_E, B): the slip torques of friction.py's laws (in the directions of the modes), then
    the composition's effects on every lane (:func:`hooks.hk_effects_lane`: the voltage at the motor,
    extra torques and lateral forces, the slip torques with the friction effects, 0 when stuck)."""
    Tcu, dTcu, bu, dbu, Tcl, bl = PT[_Tcu], PT[_dTcu], PT[_bu], PT[_dbu], PT[_Tcl], PT[_bl]
    Ts, Tc, ws, delta, bb = PT[_Ts], PT[_Tc], PT[_ws], PT[_delta], PT[_bb]
    TFU, TFL = E[_TFU], E[_TFL]
    for k in range(thu_.shape[0]):
        TFU[k], TFL[k] = _base_laws(
            wu_[k],
            wl_[k],
            MU[k],
            ML[k],
            brake,
            Tcu[k],
            dTcu[k],
            bu[k],
            dbu[k],
            Tcl[k],
            bl[k],
            Ts[k],
            Tc[k],
            ws[k],
            delta[k],
            bb[k],
        )
    hk_effects_lane(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, 1.0 if brake else 0.0, E)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def copy_rows(src, dst):
    """dst = src, row by row (a slice assignment would need numba's reference counting)."""
    for j in range(src.shape[0]):
        s = src[j]
        d = dst[j]
        for k in range(s.shape[0]):
            d[k] = s[k]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
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
            a_u, a_l, fu, fl = reduced_accelerations(
                km[k] * VOLT[k] + QU[k], string, string_on * QL[k], TFU[k], TFL[k], Ju[k], Jl[k], mu != 0.0, ml != 0.0
            )
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
            tfu, tfl = _base_laws(
                wu_[k],
                wl_[k],
                mu,
                ml,
                brake,
                Tcu[k],
                dTcu[k],
                bu[k],
                dbu[k],
                Tcl[k],
                bl[k],
                Ts[k],
                Tc[k],
                ws[k],
                delta[k],
                bb[k],
            )
            tfu = tfu if mu != 0.0 else 0.0
            tfl = tfl if ml != 0.0 else 0.0
            string = string_on * kth[k] * (thl_[k] - thu_[k])
            a_u, a_l, fu, fl = reduced_accelerations(
                km[k] * U[k], string, 0.0, tfu, tfl, Ju[k], Jl[k], mu != 0.0, ml != 0.0
            )
            K2[k] = a_u
            K3[k] = a_l
            FR0[k] = fu
            FR1[k] = fl
    if N_STATE > 8:
        for k in range(thu_.shape[0]):
            hk_states_lane(k, TT[k] + tc, U[k], thu_[k], thl_[k], wu_[k], wl_[k], 0.0, 0.0, 0.0, 0.0, Y, 4, PT, cfg, K)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E):
    """All four coordinates, the lateral constraints of docs/model.md plus the effects' forces
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
        a_u, a_l, _, _, _, fl = full_accelerations(
            x,
            yy,
            vx,
            vy,
            W,
            wl,
            s,
            c,
            mr[k] + mt[k],
            e_[k] * mr[k],
            Ju[k],
            Jl[k],
            km[k] * VOLT[k] + QU[k],
            string,
            QL[k],
            TFU[k],
            TFL[k],
            Qu,
            Qx + QX[k],
            Qy + QY[k],
            mu != 0.0,
            ml != 0.0,
        )
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
        _, s01, _, g0, _, F2, F3 = coupled_system(
            x,
            yy,
            vx,
            vy,
            W,
            wl,
            s,
            c,
            m,
            P,
            Ju[k],
            Jl[k],
            km[k] * VOLT[k] + QU[k],
            string,
            QL[k],
            tfu,
            0.0,
            Qu,
            Qx + QX[k],
            Qy + QY[k],
            mu != 0.0,
            ML[k] != 0.0,
        )
        a_u = K4[k]
        a_l = K5[k]
        a_x, a_y = lateral_accelerations(x, yy, s, c, m, P, F2, F3, a_u, a_l)
        K6[k] = a_x
        K7[k] = a_y
        FR0[k] = tfu if mu != 0.0 else g0 - s01 * a_l
    if N_STATE > 8:
        for k in range(thu_.shape[0]):
            hk_states_lane(
                k, TT[k] + tc, U[k], thu_[k], thl_[k], wu_[k], wl_[k], x_[k], y_[k], vx_[k], vy_[k], Y, 8, PT, cfg, K
            )


@njit(inline="always")
def lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, K, FR, TT, tc, cfg, E):
    """The derivative of every lane: :func:`derivative_full` (lateral, coupled) or :func:`derivative_diag`."""
    if full:
        derivative_full(Y, MU, ML, U, PT, brake, K, FR, TT, tc, cfg, E)
    else:
        derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR, TT, tc, cfg, E)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def lag_exact(S0, Yo, U, PT, TT, h, full, cfg):
    """The declared lag states (``Input.lag``) of every lane at h after the step start, exactly
    (as the scalar kernel's ``hk_lag``): rows nm + j of Yo from the start states S0."""
    nm = 8 if full else 4
    for k in range(S0.shape[1]):
        if full:
            hk_lag_lane(
                k,
                TT[k],
                U[k],
                S0[0, k],
                S0[1, k],
                S0[4, k],
                S0[5, k],
                S0[2, k],
                S0[3, k],
                S0[6, k],
                S0[7, k],
                S0,
                nm,
                PT,
                cfg,
                h,
                Yo,
            )
        else:
            hk_lag_lane(
                k, TT[k], U[k], S0[0, k], S0[1, k], S0[2, k], S0[3, k], 0.0, 0.0, 0.0, 0.0, S0, nm, PT, cfg, h, Yo
            )


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def axpy(X0, h, KX, out):
    """out = X0 + h KX, row by row."""
    for j in range(X0.shape[0]):
        x0 = X0[j]
        kx = KX[j]
        o = out[j]
        for k in range(x0.shape[0]):
            o[k] = x0[k] + h * kx[k]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
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
    K2 = W[n : 2 * n]
    K3 = W[2 * n : 3 * n]
    K4 = W[3 * n : 4 * n]
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


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
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


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
def lanes_erk(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W, TT, cfg, E, A, b, c):
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
        lane_derivative(Y, MU, ML, U, PT, full, string_on, brake, W[i * n : (i + 1) * n], FR, TT, c[i] * h, cfg, E)
    stage_sum(S0, K1, W, b, s, h, S)
    if HAS_LAG:
        lag_exact(S0, S, U, PT, TT, h, full, cfg)
    lane_derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR, TT, h, cfg, E)
    nm = 8 if full else 4  # mechanical rows; the velocities from row nm // 2
    event_check(S, FR, MU, ML, PT, full, string_on, brake, free_vibration, OK, TT, h, nm, nm // 2)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", _nrt=False)
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
        lo_u, hi_u = hk_bounds_u_lane(
            -Tcu[k] + dTcu[k], Tcu[k] + dTcu[k], k, t, thu, thl, wu, wl, x, yy, vx, vy, S, nm, PT, 0.0
        )
        gu = mu * wu if mu != 0.0 else min(hi_u - fu, fu - lo_u)
        gu = 1.0 if free_vibration else gu
        lim = Ts[k] if brake else Tcl[k]
        lo_l, hi_l = hk_bounds_l_lane(-lim, lim, k, t, thu, thl, wu, wl, x, yy, vx, vy, S, nm, PT, bf)
        gl = ml * wl if ml != 0.0 else min(hi_l - fl, fl - lo_l)
        gl = gl if string_on > 0.0 else 1.0
        OK[k] = 1 if (gu >= 0.0 and gl >= 0.0) else 0
