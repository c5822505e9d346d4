"""Lane-parallel (SIMD) RK4 kernel for batches of the diagonal-mass configurations.

For ``upper``, ``torsional`` and ``free_vibration`` the mass matrix is
diagonal (the report's reduced equations (3.19), (3.20)), so one RK4 step of B
trajectories is the same arithmetic on B lanes.  This module lays the batch
out as structure-of-arrays and writes the step branch-free, so that LLVM
vectorises it (AVX2/AVX-512): friction modes become selects, and ``exp``/``log``
are the vectorisable versions below (libm calls would block vectorisation).

Exactness is kept by construction: every lane takes the vectorised step, then
its event functions are checked (same definitions as :mod:`drillgym.integrators`);
a lane whose step crossed an event (a slipping disc reaching zero speed, a stuck
disc's torque leaving its stick set) is rolled back and re-stepped with the
scalar event-locating ``hybrid_step``.  Events are rare (a few per stick-slip
period of thousands of steps), so the batch runs at SIMD speed.

Used automatically by :func:`drillgym.simulate_batch` and
:class:`drillgym.BatchSimulator` for RK4 with exact friction when no
position/time-dependent effect (position_friction, friction_drift) or
motor_lag is on; otherwise they use the scalar kernel.  Results agree with the
scalar kernel to rounding (tested).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .configurations import N_STATE
from .dynamics import FREE_VIBRATION, TORSIONAL, UPPER, S_TL, S_TU, S_WL, S_WU, brake_on
from .integrators import RK4_A, RK4_B, RK4_C, _alloc, hybrid_step, initial_modes, record, resolve_modes
from .params import IDX

_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LOG2E = 1.44269504088896338700e00


@intrinsic
def _f64_from_bits(typingctx, bits):
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


@intrinsic
def _bits_from_f64(typingctx, x):
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


_ROUND_MAGIC = 6755399441055744.0  # 1.5 * 2**52: x + magic rounds x to an integer held in the low bits
_ROUND_MAGIC_BITS = 0x4338000000000000
_EXP_MAGIC_BITS = 0x4330000000000000  # 2**52 as bits: OR-ing a small integer in gives 2**52 + integer


@njit(inline="always", fastmath=True, error_model="numpy")
def vexp(x: float) -> float:
    """exp(x) for -700 <= x <= 700 (clamped outside), relative error < 2e-15.

    Branch-free and free of float<->int64 conversions (which AVX2 lacks), so a loop of it vectorises.
    """
    x = min(max(x, -700.0), 700.0)
    nf = np.floor(x * _LOG2E + 0.5)
    r = (x - nf * _LN2_HI) - nf * _LN2_LO
    # Taylor series to r^13 on |r| <= ln2/2 (truncation < 1e-17)
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    p = p * r + 1.0
    n = _bits_from_f64(nf + _ROUND_MAGIC) - _ROUND_MAGIC_BITS  # the integer nf, without cvttpd2qq
    return p * _f64_from_bits((n + 1023) << 52)


@njit(inline="always", fastmath=True, error_model="numpy")
def vlog(x: float) -> float:
    """Natural log for normal positive x, relative error < 3e-15; branch-free (vectorises)."""
    bits = _bits_from_f64(x)
    m = _f64_from_bits((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)  # mantissa in [1, 2)
    ef = _f64_from_bits(_EXP_MAGIC_BITS | ((bits >> 52) & 0x7FF)) - (4503599627370496.0 + 1023.0)
    big = m > 1.4142135623730951
    m = m * 0.5 if big else m
    ef = ef + 1.0 if big else ef
    s = (m - 1.0) / (m + 1.0)  # |s| <= 0.1716
    s2 = s * s
    q = 1.0 / 23.0
    q = q * s2 + 1.0 / 21.0
    q = q * s2 + 1.0 / 19.0
    q = q * s2 + 1.0 / 17.0
    q = q * s2 + 1.0 / 15.0
    q = q * s2 + 1.0 / 13.0
    q = q * s2 + 1.0 / 11.0
    q = q * s2 + 1.0 / 9.0
    q = q * s2 + 1.0 / 7.0
    q = q * s2 + 1.0 / 5.0
    q = q * s2 + 1.0 / 3.0
    q = q * s2 + 1.0
    return 2.0 * s * q + ef * _LN2_HI + ef * _LN2_LO


# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Ju, _km, _Tcu, _dTcu, _bu, _dbu = IDX.Ju, IDX.km, IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Jl, _kth, _Tcl, _bl = IDX.Jl, IDX.ktheta, IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_asym_s, _asym_c, _dtheta = IDX.asym_s, IDX.asym_c, IDX.dtheta


@njit(cache=True, fastmath=True, error_model="numpy")
def _lanes_derivative(thu, thl, wu, wl, mu, ml, u, PT, string_on, brake, dwu, dwl, tfu_out, tfl_out):
    """Accelerations and friction torques of every lane (diagonal mass: (3.19), (3.20)).

    One straight-line loop body (modes as selects, vexp/vlog) so that LLVM vectorises it.
    A stuck disc (mode 0) gets zero acceleration and its holding torque as friction.
    """
    Ju = PT[_Ju]
    km = PT[_km]
    Tcu = PT[_Tcu]
    dTcu = PT[_dTcu]
    bu = PT[_bu]
    dbu = PT[_dbu]
    Jl = PT[_Jl]
    kth = PT[_kth]
    dth = PT[_dtheta]
    Tcl = PT[_Tcl]
    bl = PT[_bl]
    Ts = PT[_Ts]
    Tc = PT[_Tc]
    ws = PT[_ws]
    delta = PT[_delta]
    bb = PT[_bb]
    asym_s = PT[_asym_s]
    asym_c = PT[_asym_c]
    for k in range(thu.shape[0]):
        string = string_on * (kth[k] * (thl[k] - thu[k]) + dth[k] * (wl[k] - wu[k]))
        Fu = km[k] * u[k] + string
        Fl = -string
        awu = abs(wu[k])
        m_u = mu[k]
        t_pos = Tcu[k] + dTcu[k] + (bu[k] + dbu[k]) * awu
        t_neg = -(Tcu[k] - dTcu[k] + (bu[k] - dbu[k]) * awu)
        tfu = t_pos if m_u > 0.0 else (t_neg if m_u < 0.0 else Fu)
        awl = abs(wl[k])
        m_l = ml[k]
        neg = 1.0 if m_l < 0.0 else 0.0
        ts = Ts[k] * (1.0 + asym_s[k] * neg)
        tc = Tc[k] * (1.0 + asym_c[k] * neg)
        z = max(awl / ws[k], 1e-300)
        stribeck = tc + (ts - tc) * vexp(-vexp(delta[k] * vlog(z))) + bb[k] * awl
        bearing = Tcl[k] + bl[k] * awl
        mag = stribeck if brake else bearing
        tfl = m_l * mag if m_l != 0.0 else Fl
        dwu[k] = (Fu - tfu) / Ju[k] if m_u != 0.0 else 0.0
        dwl[k] = (Fl - tfl) / Jl[k] if m_l != 0.0 else 0.0
        tfu_out[k] = tfu
        tfl_out[k] = tfl


@njit(cache=True, fastmath=True, error_model="numpy")
def _axpy4(X0, h, Kx, out):
    """out[j] = X0[j] + h * Kx[j] for the four state rows (theta_u, theta_l, omega_u, omega_l)."""
    for j in range(4):
        x0 = X0[j]
        kx = Kx[j]
        o = out[j]
        for k in range(x0.shape[0]):
            o[k] = x0[k] + h * kx[k]


@njit(cache=True, fastmath=True, error_model="numpy")
def _lanes_rk4(S, K1, FR, MU, ML, U, PT, h, string_on, brake, S0, OK, free_vibration, W):
    """One classical RK4 step of every lane.

    S (4, B) = (theta_u, theta_l, omega_u, omega_l), updated in place; K1 (4, B) the
    derivative at the step start, replaced by the one at the end (reused by the next
    step); FR (2, B) friction torques at the end; S0 receives the start state; OK[k] = 1
    when lane k's event functions (as ``integrators.event_values``) stayed positive.
    W (16, B) is work space.
    """
    B = S.shape[1]
    hh = 0.5 * h
    for j in range(4):
        S0[j, :] = S[j, :]
    Y = W[0:4]
    K2 = W[4:8]
    K3 = W[8:12]
    K4 = W[12:16]
    _axpy4(S0, hh, K1, Y)
    K2[0, :] = Y[2, :]
    K2[1, :] = Y[3, :]
    _lanes_derivative(Y[0], Y[1], Y[2], Y[3], MU, ML, U, PT, string_on, brake, K2[2], K2[3], FR[0], FR[1])
    _axpy4(S0, hh, K2, Y)
    K3[0, :] = Y[2, :]
    K3[1, :] = Y[3, :]
    _lanes_derivative(Y[0], Y[1], Y[2], Y[3], MU, ML, U, PT, string_on, brake, K3[2], K3[3], FR[0], FR[1])
    _axpy4(S0, h, K3, Y)
    K4[0, :] = Y[2, :]
    K4[1, :] = Y[3, :]
    _lanes_derivative(Y[0], Y[1], Y[2], Y[3], MU, ML, U, PT, string_on, brake, K4[2], K4[3], FR[0], FR[1])
    h6 = h / 6.0
    for j in range(4):
        s = S[j]
        s0 = S0[j]
        a = K1[j]
        b = K2[j]
        c = K3[j]
        d = K4[j]
        for k in range(B):
            s[k] = s0[k] + h6 * (a[k] + 2.0 * (b[k] + c[k]) + d[k])
    K1[0, :] = S[2, :]
    K1[1, :] = S[3, :]
    _lanes_derivative(S[0], S[1], S[2], S[3], MU, ML, U, PT, string_on, brake, K1[2], K1[3], FR[0], FR[1])
    Tcu = PT[_Tcu]
    dTcu = PT[_dTcu]
    Ts = PT[_Ts]
    Tcl = PT[_Tcl]
    asym_s = PT[_asym_s]
    for k in range(B):
        fu = FR[0, k]
        fl = FR[1, k]
        mu = MU[k]
        ml = ML[k]
        gu = mu * S[2, k] if mu != 0.0 else min(Tcu[k] + dTcu[k] - fu, fu + Tcu[k] - dTcu[k])
        gu = 1.0 if free_vibration else gu
        hi_l = Ts[k] if brake else Tcl[k]
        lo_l = -Ts[k] * (1.0 + asym_s[k]) if brake else -Tcl[k]
        gl = ml * S[3, k] if ml != 0.0 else min(hi_l - fl, fl - lo_l)
        gl = gl if string_on > 0.0 else 1.0
        OK[k] = 1 if (gu >= 0.0 and gl >= 0.0) else 0


@njit(cache=True)
def _sync_lane_to_state(S, K1, FR, MU, ML, k, y, k1, fric, mode):
    y[S_TU] = S[0, k]
    y[S_TL] = S[1, k]
    y[S_WU] = S[2, k]
    y[S_WL] = S[3, k]
    for j in range(4):
        k1[j] = K1[j, k]
    fric[0] = FR[0, k]
    fric[1] = FR[1, k]
    mode[0] = np.int64(MU[k])
    mode[1] = np.int64(ML[k])


@njit(cache=True)
def _sync_state_to_lane(S, K1, FR, MU, ML, k, y, k1, fric, mode):
    S[0, k] = y[S_TU]
    S[1, k] = y[S_TL]
    S[2, k] = y[S_WU]
    S[3, k] = y[S_WL]
    for j in range(4):
        K1[j, k] = k1[j]
    FR[0, k] = fric[0]
    FR[1, k] = fric[1]
    MU[k] = float(mode[0])
    ML[k] = float(mode[1])


def lanes_eligible(cfg: int, method: str, eps: float, P: np.ndarray) -> bool:
    """True when the lane kernel computes exactly what the scalar kernel would: RK4, exact
    friction, a diagonal-mass configuration, and no motor_lag / position_friction /
    friction_drift (their extra state or angle/time dependence is scalar-only)."""
    if method.lower() != "rk4" or eps > 0.0 or cfg not in (UPPER, TORSIONAL, FREE_VIBRATION):
        return False
    off = P[:, [IDX.tau_m, IDX.pf_a1, IDX.pf_a2, IDX.drift]]
    return bool(np.all(off == 0.0))


@njit(cache=True, nogil=True)
def lanes_run(Y, MODE, U, P, cfg, dt, T0, rec_every, OUT, n_steps, init_modes, FRIC_OUT):
    """Batch run on lanes: same contract as integrators.run_batch_serial (RK4, exact friction),
    plus n_steps (U may hold one column when constant) and FRIC_OUT (B, 2) final friction.
    OUT may have zero rows (no recording)."""
    B = Y.shape[0]
    PT = np.ascontiguousarray(P.T)
    S = np.empty((4, B))
    S0 = np.empty((4, B))
    K1 = np.zeros((4, B))
    FR = np.zeros((2, B))
    MU = np.zeros(B)
    ML = np.zeros(B)
    OK = np.zeros(B, dtype=np.int64)
    W = np.zeros((16, B))
    Ucur = np.empty(B)
    Uprev = np.empty(B)
    A, b, c = RK4_A, RK4_B, RK4_C
    K, ytmp, M, Bw = _alloc(4)
    y = np.zeros(N_STATE)
    k1 = np.zeros(N_STATE)
    ynew = np.zeros(N_STATE)
    fric = np.zeros(2)
    ftmp = np.zeros(2)
    g0 = np.zeros(2)
    g1 = np.zeros(2)
    mode = np.zeros(2, dtype=np.int64)
    string_on = 0.0 if cfg == UPPER else 1.0
    brake = brake_on(cfg)
    fv = cfg == FREE_VIBRATION
    n_u = U.shape[1]
    record_on = OUT.shape[1] > 0
    for k in range(B):
        for j in range(N_STATE):
            y[j] = Y[k, j]
        for j in range(2):
            mode[j] = MODE[k, j]
        u0 = U[k, 0]
        if init_modes:
            initial_modes(T0[k], y, u0, P[k], cfg, mode, k1, fric, M, Bw)
        else:
            resolve_modes(T0[k], y, mode, u0, P[k], cfg, k1, fric, M, Bw)
        _sync_state_to_lane(S, K1, FR, MU, ML, k, y, k1, fric, mode)
        for j in range(N_STATE):
            Y[k, j] = y[j]
        if record_on:
            record(OUT[k], 0, T0[k], u0, y, fric, mode)
        Uprev[k] = u0
    for i in range(n_steps):
        col = i if n_u > 1 else 0
        for k in range(B):
            Ucur[k] = U[k, col]
        # a changed input can release a stuck disc: resolve those lanes first (scalar, rare)
        for k in range(B):
            if Ucur[k] != Uprev[k]:
                for j in range(N_STATE):
                    y[j] = Y[k, j]
                _sync_lane_to_state(S, K1, FR, MU, ML, k, y, k1, fric, mode)
                resolve_modes(T0[k] + i * dt, y, mode, Ucur[k], P[k], cfg, k1, fric, M, Bw)
                _sync_state_to_lane(S, K1, FR, MU, ML, k, y, k1, fric, mode)
                Uprev[k] = Ucur[k]
        _lanes_rk4(S, K1, FR, MU, ML, Ucur, PT, dt, string_on, brake, S0, OK, fv, W)
        for k in range(B):
            if OK[k] == 0:  # an event inside this step: redo it exactly on the scalar path
                for j in range(N_STATE):
                    y[j] = Y[k, j]
                y[S_TU] = S0[0, k]
                y[S_TL] = S0[1, k]
                y[S_WU] = S0[2, k]
                y[S_WL] = S0[3, k]
                mode[0] = np.int64(MU[k])
                mode[1] = np.int64(ML[k])
                t = T0[k] + i * dt
                resolve_modes(t, y, mode, Ucur[k], P[k], cfg, k1, fric, M, Bw)
                hybrid_step(t, y, k1, fric, mode, Ucur[k], P[k], cfg, 0.0, dt, A, b, c, K, ytmp, ynew, M, Bw,
                            g0, g1, ftmp)
                _sync_state_to_lane(S, K1, FR, MU, ML, k, y, k1, fric, mode)
        if record_on and (i + 1) % rec_every == 0:
            row = (i + 1) // rec_every
            ncol = i + 1 if i + 1 < n_u else n_u - 1
            for k in range(B):
                for j in range(N_STATE):
                    y[j] = Y[k, j]
                y[S_TU] = S[0, k]
                y[S_TL] = S[1, k]
                y[S_WU] = S[2, k]
                y[S_WL] = S[3, k]
                fric[0] = FR[0, k]
                fric[1] = FR[1, k]
                mode[0] = np.int64(MU[k])
                mode[1] = np.int64(ML[k])
                record(OUT[k], row, T0[k] + (i + 1) * dt, U[k, ncol] if n_u > 1 else Ucur[k], y, fric, mode)
    for k in range(B):
        Y[k, S_TU] = S[0, k]
        Y[k, S_TL] = S[1, k]
        Y[k, S_WU] = S[2, k]
        Y[k, S_WL] = S[3, k]
        MODE[k, 0] = np.int64(MU[k])
        MODE[k, 1] = np.int64(ML[k])
        FRIC_OUT[k, 0] = FR[0, k]
        FRIC_OUT[k, 1] = FR[1, k]
