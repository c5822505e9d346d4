"""Lane-parallel (SIMD) RK4 kernel: a batch of trajectories as one vectorised loop.

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

Used automatically by :func:`drillgym.simulate_batch` and
:class:`drillgym.BatchSimulator` for batches of 8 or more with RK4 and exact
friction, unless an effect with scalar-only formulas is on (see
``lanes_eligible``).  Results agree with the scalar kernel to rounding (tested).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .configurations import N_STATE
from .dynamics import FREE_VIBRATION, UPPER, S_TL, S_TU, S_VX, S_VY, S_WL, S_WU, S_X, S_Y, brake_on, lateral_free
from .integrators import RK4_A, RK4_B, RK4_C, alloc_work, hybrid_step, initial_modes, record, resolve_modes
from .friction import bearing_law, brake_law_simd, upper_law
from .dynamics import full_accelerations, isotropic_lateral_forces, reduced_accelerations
from .params import IDX
from .vmath import vsincos

# parameter rows of the structure-of-arrays parameter matrix PT (n_params, B)
_Ju, _km, _Tcu, _dTcu, _bu, _dbu = IDX.Ju, IDX.km, IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Jl, _kth, _Tcl, _bl = IDX.Jl, IDX.ktheta, IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e
_asym_s, _asym_c, _dtheta = IDX.asym_s, IDX.asym_c, IDX.dtheta

# lane state rows -> state vector indices: diagonal mass (theta_u, theta_l, omega_u, omega_l);
# full (theta_u, theta_l, x, y, omega_u, omega_l, vx, vy): positions first, then their velocities
ROWS_DIAG = np.array([S_TU, S_TL, S_WU, S_WL])
ROWS_FULL = np.array([S_TU, S_TL, S_X, S_Y, S_WU, S_WL, S_VX, S_VY])


@njit(inline="always", fastmath=True, error_model="numpy")
def _friction_laws(wu, wl, mu, ml, Tcu, dTcu, bu, dbu, Tcl, bl, Ts, Tc, ws, delta, bb, asym_s, asym_c, brake):
    """Slip friction torques (N m) in the directions of the modes (0 for a stuck disc): friction.py's laws."""
    awl = abs(wl)
    tfl = brake_law_simd(awl, ml, Ts, Tc, ws, delta, bb, asym_s, asym_c) if brake else bearing_law(awl, ml, Tcl, bl)
    return upper_law(abs(wu), mu, Tcu, dTcu, bu, dbu), tfl


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _copy_rows(src, dst):
    """dst = src, row by row (a slice assignment would need numba's reference counting)."""
    for j in range(src.shape[0]):
        s = src[j]
        d = dst[j]
        for k in range(s.shape[0]):
            d[k] = s[k]


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR):
    """Diagonal mass ((3.19), (3.20)): K[0:2] = speeds, K[2:4] = accelerations, FR = friction
    torques (a stuck disc: zero acceleration, friction = its holding torque).
    Rows are taken as 1-D views first and each loop writes at most four arrays: that is what lets
    LLVM vectorise it (more written arrays exceed its runtime alias-check budget)."""
    thu, thl, wu_, wl_ = Y[0], Y[1], Y[2], Y[3]
    K2, K3, FR0, FR1 = K[2], K[3], FR[0], FR[1]
    Ju, km, Jl, kth, dth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth], PT[_dtheta]
    Tcu, dTcu, bu, dbu, Tcl, bl = PT[_Tcu], PT[_dTcu], PT[_bu], PT[_dbu], PT[_Tcl], PT[_bl]
    Ts, Tc, ws, delta, bb, asym_s, asym_c = PT[_Ts], PT[_Tc], PT[_ws], PT[_delta], PT[_bb], PT[_asym_s], PT[_asym_c]
    _copy_rows(Y[2:4], K[0:2])  # angle rates = speeds
    for k in range(thu.shape[0]):
        wu = wu_[k]
        wl = wl_[k]
        mu = MU[k]
        ml = ML[k]
        string = string_on * (kth[k] * (thl[k] - thu[k]) + dth[k] * (wl - wu))
        tfu, tfl = _friction_laws(wu, wl, mu, ml, Tcu[k], dTcu[k], bu[k], dbu[k], Tcl[k], bl[k], Ts[k], Tc[k],
                                  ws[k], delta[k], bb[k], asym_s[k], asym_c[k], brake)
        a_u, a_l, fu, fl = reduced_accelerations(km[k] * U[k], string, tfu, tfl, Ju[k], Jl[k], mu != 0.0, ml != 0.0)
        K2[k] = a_u
        K3[k] = a_l
        FR0[k] = fu
        FR1[k] = fl


@njit(cache=True, fastmath=True, error_model="numpy", _nrt=False)
def _derivative_full(Y, MU, ML, U, PT, brake, K, FR):
    """All four coordinates, isotropic lateral constraints (dynamics.state_derivative's formulas,
    Schur complement of the m I block, stuck discs as selects)."""
    thu_, thl_, x_, y_, wu_, wl_, vx_, vy_ = Y[0], Y[1], Y[2], Y[3], Y[4], Y[5], Y[6], Y[7]
    _copy_rows(Y[4:8], K[0:4])  # position rates = velocities
    Ju, km, Jl, kth, dth = PT[_Ju], PT[_km], PT[_Jl], PT[_kth], PT[_dtheta]
    Tcu, dTcu, bu, dbu, Tcl, bl = PT[_Tcu], PT[_dTcu], PT[_bu], PT[_dbu], PT[_Tcl], PT[_bl]
    Ts, Tc, ws, delta, bb_, asym_s, asym_c = PT[_Ts], PT[_Tc], PT[_ws], PT[_delta], PT[_bb], PT[_asym_s], PT[_asym_c]
    mr, mt, k_, b_, e_ = PT[_mr], PT[_mt], PT[_k], PT[_b], PT[_e]
    for k in range(thu_.shape[0]):
        x = x_[k]
        yy = y_[k]
        W = wu_[k]
        wl = wl_[k]
        vx = vx_[k]
        vy = vy_[k]
        mu = MU[k]
        ml = ML[k]
        alpha = thl_[k] - thu_[k]
        s, c = vsincos(alpha)
        string = kth[k] * alpha + dth[k] * (wl - W)
        tfu, tfl = _friction_laws(W, wl, mu, ml, Tcu[k], dTcu[k], bu[k], dbu[k], Tcl[k], bl[k], Ts[k], Tc[k],
                                  ws[k], delta[k], bb_[k], asym_s[k], asym_c[k], brake)
        Qu, Qx, Qy = isotropic_lateral_forces(x, yy, vx, vy, W, k_[k], b_[k])
        a_u, a_l, a_x, a_y, fu, fl = full_accelerations(x, yy, vx, vy, W, wl, s, c, mr[k] + mt[k], e_[k] * mr[k],
                                                        Ju[k], Jl[k], km[k] * U[k], string, tfu, tfl, Qu, Qx, Qy,
                                                        mu != 0.0, ml != 0.0)
        K[4, k] = a_u
        K[5, k] = a_l
        K[6, k] = a_x
        K[7, k] = a_y
        FR[0, k] = fu
        FR[1, k] = fl


@njit(inline="always")
def _derivative(Y, MU, ML, U, PT, full, string_on, brake, K, FR):
    if full:
        _derivative_full(Y, MU, ML, U, PT, brake, K, FR)
    else:
        _derivative_diag(Y, MU, ML, U, PT, string_on, brake, K, FR)


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
def _lanes_rk4(S, K1, FR, MU, ML, U, PT, h, full, string_on, brake, free_vibration, S0, OK, W):
    """One classical RK4 step of every lane.

    S (n, B) lane states (rows ROWS_DIAG or ROWS_FULL), updated in place; K1 (n, B) the
    derivative at the step start, replaced by the one at the end (reused by the next step);
    FR (2, B) friction torques at the end; S0 receives the start state; OK[k] = 1 when lane k's
    event functions (as ``integrators.event_values``) stayed positive.  W (4n, B) work space.
    """
    n = S.shape[0]
    B = S.shape[1]
    hv = n // 2  # first velocity row
    _copy_rows(S, S0)
    Y = W[0:n]
    K2 = W[n:2 * n]
    K3 = W[2 * n:3 * n]
    K4 = W[3 * n:4 * n]
    _axpy(S0, 0.5 * h, K1, Y)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K2, FR)
    _axpy(S0, 0.5 * h, K2, Y)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K3, FR)
    _axpy(S0, h, K3, Y)
    _derivative(Y, MU, ML, U, PT, full, string_on, brake, K4, FR)
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
    _derivative(S, MU, ML, U, PT, full, string_on, brake, K1, FR)
    wu_row = S[hv]
    wl_row = S[hv + 1]
    for k in range(B):
        fu = FR[0, k]
        fl = FR[1, k]
        mu = MU[k]
        ml = ML[k]
        gu = mu * wu_row[k] if mu != 0.0 else min(PT[_Tcu, k] + PT[_dTcu, k] - fu, fu + PT[_Tcu, k] - PT[_dTcu, k])
        gu = 1.0 if free_vibration else gu
        hi_l = PT[_Ts, k] if brake else PT[_Tcl, k]
        lo_l = -PT[_Ts, k] * (1.0 + PT[_asym_s, k]) if brake else -PT[_Tcl, k]
        gl = ml * wl_row[k] if ml != 0.0 else min(hi_l - fl, fl - lo_l)
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


def lanes_eligible(cfg: int, method: str, eps: float, P: np.ndarray) -> bool:
    """True when the lane kernel computes what the scalar kernel computes: RK4, exact friction,
    and no motor_lag / position_friction / friction_drift (extra state, angle or time
    dependence) nor anisotropic / dry-friction lateral constraints (scalar-only formulas)."""
    if method.lower() != "rk4" or eps > 0.0:
        return False
    off = P[:, [IDX.tau_m, IDX.pf_a1, IDX.pf_a2, IDX.drift, IDX.dk, IDX.db, IDX.Fc_lat]]
    return bool(np.all(off == 0.0))


@njit(cache=True, nogil=True)
def lanes_run(Y, MODE, U, P, cfg, dt, T0, rec_every, OUT, n_steps, init_modes, FRIC_OUT):
    """Batch run on lanes: same contract as integrators.run_batch_serial (RK4, exact friction),
    plus n_steps (U may hold one column when constant) and FRIC_OUT (B, 2) final friction.
    OUT may have zero samples (no recording)."""
    B = Y.shape[0]
    full = lateral_free(cfg)
    rows = ROWS_FULL if full else ROWS_DIAG
    n = rows.shape[0]
    PT = np.ascontiguousarray(P.T)
    S = np.empty((n, B))
    S0 = np.empty((n, B))
    K1 = np.zeros((n, B))
    FR = np.zeros((2, B))
    MU = np.zeros(B)
    ML = np.zeros(B)
    OK = np.zeros(B, dtype=np.int64)
    W = np.zeros((4 * n, B))
    Ucur = np.empty(B)
    Uprev = np.empty(B)
    A, b, c = RK4_A, RK4_B, RK4_C
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(4)
    y = np.zeros(N_STATE)
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
            initial_modes(T0[k], y, u0, P[k], cfg, mode, k1, fric)
        else:
            resolve_modes(T0[k], y, mode, u0, P[k], cfg, k1, fric)
        _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
        for j in range(N_STATE):
            Y[k, j] = y[j]
        if record_on:
            record(OUT[k], 0, T0[k], u0, y, fric, mode)
        Uprev[k] = u0
    for i in range(n_steps):
        col = i if n_u > 1 else 0
        for k in range(B):
            Ucur[k] = U[k, col]
            if Ucur[k] != Uprev[k]:  # a new input can release a stuck disc: resolve (scalar, rare)
                y[:] = Y[k]
                _lane_to_state(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
                resolve_modes(T0[k] + i * dt, y, mode, Ucur[k], P[k], cfg, k1, fric)
                _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
                Uprev[k] = Ucur[k]
        _lanes_rk4(S, K1, FR, MU, ML, Ucur, PT, dt, full, string_on, brake, fv, S0, OK, W)
        for k in range(B):
            if OK[k] == 0:  # an event inside this step: redo it exactly on the scalar path
                y[:] = Y[k]
                for j in range(n):
                    y[rows[j]] = S0[j, k]
                mode[0] = np.int64(MU[k])
                mode[1] = np.int64(ML[k])
                t = T0[k] + i * dt
                resolve_modes(t, y, mode, Ucur[k], P[k], cfg, k1, fric)
                hybrid_step(t, y, k1, fric, mode, Ucur[k], P[k], cfg, 0.0, dt, A, b, c, K, ytmp, ynew,
                            g0, g1, ftmp)
                _state_to_lane(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
        if record_on and (i + 1) % rec_every == 0:
            row = (i + 1) // rec_every
            ncol = i + 1 if i + 1 < n_u else n_u - 1
            for k in range(B):
                y[:] = Y[k]
                _lane_to_state(S, K1, FR, MU, ML, rows, k, y, k1, fric, mode)
                record(OUT[k], row, T0[k] + (i + 1) * dt, U[k, ncol], y, fric, mode)
    for k in range(B):
        for j in range(n):
            Y[k, rows[j]] = S[j, k]
        MODE[k, 0] = np.int64(MU[k])
        MODE[k, 1] = np.int64(ML[k])
        FRIC_OUT[k, 0] = FR[0, k]
        FRIC_OUT[k, 1] = FR[1, k]
