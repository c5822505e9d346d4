"""The ``observer`` controller's law compiled: extended Kalman filter on the motor angle + flatness law.

What :meth:`controllers.observer.ObserverController.act` computes each period, for every lane, on a model
without effects (the base torsional model, the state ``d`` the brake's level or an offset, optionally the
upper-disc torque ``du``): the filter's update with the measured motor angle (Joseph form), the
feedback-linearising law of :class:`controllers.flatness.FlatnessLaw` on the estimates (its reference
lags, the integral of the speed error or of the motor angle's), the clip, then the filter's prediction
with the applied voltage (the exponential Euler mean of :meth:`controllers.kalman.DisturbanceModel.predict_mean`,
the covariance with its Jacobian).

Arithmetic on lanes (structure of arrays, one row per quantity): the loops over the lanes vectorise; the
brake's Stribeck law uses the vectorisable exp and log of :mod:`drillgym.vmath` (relative error below
2e-15 against libm's).  The Jacobian of the right-hand side is taken analytically where the model is linear
(the reference differences it numerically, exact there to its round-off) and by the same central
differences as the reference in the speeds (the friction laws), with the modes resolved as
:class:`controllers.dynamics.ModelDynamics` resolves them (a disc slower than ``eps`` at rest unless its
holding torque leaves the stick set).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE, M_REF, M_TU
from drillgym.vmath import FASTMATH, vexp, vlog

from ..flatness import ANGLE_STEP, TRIM_BAND, TRIM_CLIP

__all__ = [
    "observer_step",
    "observer_law",
    "model_rhs",
    "jacobian",
    "brake_shapes",
    "observer_transition",
    "covariance_products",
    "ROWS",
    "CONSTANTS",
    "MAX_DIM",
]

MAX_DIM = 6
# state rows: estimates (MAX_DIM), covariance (MAX_DIM^2, row-major in the model's dim), then the law's
_X0 = 0
_P0 = MAX_DIM
_L0 = _P0 + MAX_DIM * MAX_DIM
ROWS = ("y1", "y2", "y3", "z", "t", "target", "low", "k0", "k1", "k2", "k3", "settle", "integrating", "theta0", "t_int")
"""The flatness law's rows, from its first (:func:`law_rows`)."""
Y1, Y2, Y3, Z, TL, TARGET, LOW, K0, K1, K2, K3, SETTLE, INTEG, THETA0, TINT = range(len(ROWS))
# then work rows, rewritten every period: the filter's (W: gain, then products), the model's right-hand side and
# Jacobian, the brake law's shapes (three speeds of the law, three of the model), the law's torques
_W0 = _L0 + len(ROWS)
_F0 = _W0 + 2 * MAX_DIM * MAX_DIM + MAX_DIM
_J0 = _F0 + MAX_DIM
_S0 = _J0 + MAX_DIM * MAX_DIM
_T0 = _S0 + 6
N_ROWS = _T0 + 4

CONSTANTS = (
    "dt", "r", "eps", "h", "Ju", "Jl", "km", "kth", "Tcu", "dTcu", "bu", "dbu", "Ts", "Tc", "ws", "delta", "bb",
    "tau", "w_rest", "hf", "hold", "ramp", "approach", "u_max", "scale", "has_du", "trim_gain", "trim_band",
    "trim_clip", "dim",
)  # fmt: skip
(DT, R, EPS, H, JU, JL, KM, KTH, TCU, DTCU, BU, DBU, TS, TC, WS, DELTA, BB,
 TAU, W_REST, HF, HOLD, RAMP, APPROACH, U_MAX, SCALE, HAS_DU, TRIM_GAIN, BAND, REACH,
 DIM) = range(len(CONSTANTS))  # fmt: skip
_MAT0 = len(CONSTANTS)  # then Ad, Gamma, Ac, Qd (dim x dim each, row-major)


@njit(inline="always")
def _shape(aw, ws, delta):
    """exp(-(aw/ws)^delta): the Stribeck law's decay at speed magnitude aw (rad/s), vectorisable."""
    z = max(aw / ws, 1e-300)
    return vexp(-vexp(delta * vlog(z)))


@njit(inline="always")
def _upper(aw, d, Tcu, dTcu, bu, dbu):
    """Upper slip torque (N m), :func:`drillgym.friction.upper_law`."""
    t_pos = Tcu + dTcu + (bu + dbu) * aw
    t_neg = -(Tcu - dTcu + (bu - dbu) * aw)
    return t_pos if d > 0 else (t_neg if d < 0 else 0.0)


@njit(inline="always")
def _sign(x):
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def brake_shapes(wl_, C, n, SH):
    """The brake law's shapes (:func:`_shape`) from the lower-speed estimates wl_ (rad/s): the law's at
    ww = max(wl, w_rest + hf) and ww +- hf into the rows SH[0:3], the model's and its Jacobian's at |wl| and
    |wl +- h| into SH[3:6].  One loop of five shapes per lane, not six: the law's shape at ww is the model's at
    |wl| where wl >= max(ww, 0), and else the shape at w_rest + hf (:func:`_shape` takes a speed at or below 0 as
    0).  The exp and log inside fuse their polynomials' steps (:func:`drillgym.vmath.fma`)."""
    ws, delta, h, hf = C[WS], C[DELTA], C[H], C[HF]
    lo = C[W_REST] + hf
    at_lo, moving = _shape(lo, ws, delta), max(lo, 0.0)
    for k in range(n):
        wl = wl_[k]
        ww = max(wl, lo)
        e = _shape(abs(wl), ws, delta)
        SH[0, k] = e if wl >= moving else at_lo
        SH[1, k] = _shape(ww + hf, ws, delta)
        SH[2, k] = _shape(ww - hf, ws, delta)
        SH[3, k] = e
        SH[4, k] = _shape(abs(wl + h), ws, delta)
        SH[5, k] = _shape(abs(wl - h), ws, delta)


@njit(cache=True, error_model="numpy")
def update(M, X, r, n, dim, p0, W):
    """The filter's update with the measured motor angles (Joseph form): estimates in rows 0.., covariance from
    row p0; r the angle's variance (rad^2); W: work rows (>= 3 dim + 1: the gain, the prior's first row and column,
    the innovation).

    P = A (I - K e0')' + r K K' with A = (I - K e0') P, element by element in one pass over the covariance:
    P_ij - K_i P_0j - (P_i0 - K_i P_00) K_j + r K_i K_j, the products and sums of the two-pass form in its order."""
    innovation = W[3 * dim]
    for k in range(n):
        innovation[k] = M[M_TU, k] - X[_X0, k]
    for i in range(dim):  # the lanes innermost, so that the loops vectorise
        for k in range(n):
            g = X[p0 + i * dim, k] / (X[p0, k] + r)  # K = P e0 / (e0' P e0 + r)
            W[i, k] = g
            X[_X0 + i, k] += g * innovation[k]
    for i in range(dim):  # the prior's first row and column (the pass below overwrites them)
        for k in range(n):
            W[dim + i, k] = X[p0 + i, k]
            W[2 * dim + i, k] = X[p0 + i * dim, k]
    for i in range(dim):
        gi = W[i]
        pi0 = W[2 * dim + i]
        for j in range(dim):
            gj = W[j]
            p0j = W[dim + j]
            row = X[p0 + i * dim + j]
            for k in range(n):
                a = row[k] - gi[k] * p0j[k]  # A_ij
                a0 = pi0[k] - gi[k] * W[dim, k]  # A_i0
                row[k] = (a - a0 * gj[k]) + r * gi[k] * gj[k]


@njit(cache=True, error_model="numpy")
def base_torques(X, C, n, SH, TQ):
    """The law's torques of the model without effects into the rows TQ (N m): the brake law at the law's speed
    ww and ww +- hf (:func:`brake_shapes` in SH[0:3]), the upper friction at the estimated upper speed."""
    Ts, Tc, bb, hf, w_rest = C[TS], C[TC], C[BB], C[HF], C[W_REST]
    for k in range(n):
        ww = max(X[_X0 + 3, k], w_rest + hf)
        TQ[0, k] = Tc + (Ts - Tc) * SH[0, k] + bb * ww
        TQ[1, k] = Tc + (Ts - Tc) * SH[1, k] + bb * (ww + hf)
        TQ[2, k] = Tc + (Ts - Tc) * SH[2, k] + bb * (ww - hf)
        wu = X[_X0 + 1, k]
        w0 = 1e-9 if wu == 0 else wu
        TQ[3, k] = _upper(abs(w0), _sign(w0), C[TCU], C[DTCU], C[BU], C[DBU])


@njit(error_model="numpy")  # LLVM inlines it: inlined by numba (inline="always") the loops stay scalar
def _reference(L, k, hold, ramp, approach, tau):
    """Lane k's reference, three lags of the setpoint (FlatnessLaw.reference), from the law's rows L before the
    period: the setpoint w and the lags' derivatives d1, d2, d3, their differences dd2, dd3 and r3 (1/s^3)."""
    t_old, target = L[TL, k], L[TARGET, k]
    step = 1.0 if t_old >= hold else 0.0
    s = min(max((t_old - hold) / ramp, 0.0), 1.0) if ramp > 0 else step
    w = approach + s * (target - approach) if L[LOW, k] > 0 else target
    y1, y2, r = L[Y1, k], L[Y2, k], L[Y3, k]
    d1, d2, d3 = (w - y1) / tau, (y1 - y2) / tau, (y2 - r) / tau
    dd2, dd3 = (d1 - d2) / tau, (d2 - d3) / tau
    return d1, d2, d3, dd3, (dd2 - dd3) / tau


@njit(cache=True, error_model="numpy")
def flatness_law(M, X, L, C, n, U, TQ):
    """The flatness law's voltage (V, not clipped) from the updated estimates (rows 0.. of X), its rows L
    (:data:`ROWS`) advanced; TQ the torques (N m): the brake law at the law's speed ww and ww +- hf, the upper
    disc's at the estimated upper speed (:func:`base_torques`, or the model's with its effects).

    Three loops, each branch-free on the lanes' values and on the settings (selects; a row the reference leaves
    is stored back unchanged) and each storing few rows, so that each vectorises (a loop storing many rows needs
    more run-time alias checks than LLVM takes): the target's trim, the law on the lags before the period, the
    lags and the clock advanced."""
    dt, tau, kt, Jl, Ju, km = C[DT], C[TAU], C[KTH], C[JL], C[JU], C[KM]
    hf, w_rest = C[HF], C[W_REST]
    hold, ramp, approach = C[HOLD], C[RAMP], C[APPROACH]
    band, reach_share = C[BAND], C[REACH]
    scale, has_du, gain = C[SCALE] > 0, C[HAS_DU] > 0, C[TRIM_GAIN]
    trims = gain > 0
    for k in range(n):  # the target trimmed by the motor angle's error (ObserverController._trim)
        ref, wl = M[M_REF, k], X[_X0 + 3, k]
        start = trims & (L[TL, k] >= L[SETTLE, k]) & (L[INTEG, k] == 0.0) & (abs(wl - ref) <= band * abs(ref))
        theta0 = X[_X0, k] if start else L[THETA0, k]
        integrating = 1.0 if start else L[INTEG, k]
        L[THETA0, k], L[INTEG, k] = theta0, integrating
        trimming = trims & (integrating > 0)
        t_int = L[TINT, k] + dt if trimming else L[TINT, k]
        L[TINT, k] = t_int
        z = X[_X0, k] - theta0 - ref * t_int
        reach = reach_share * abs(ref)
        trimmed = min(max(ref - gain * z, ref - reach), ref + reach)
        L[TARGET, k] = trimmed if trimming else L[TARGET, k]
    # rows 4-9 of TQ for a model with effects, else row 0 again (read, then left out by the selects)
    angle_rows = TQ.shape[0] > 4
    ap_row, am_row = (4, 5) if angle_rows else (0, 0)
    pp_row, pm_row, mp_row, mm_row = (6, 7, 8, 9) if angle_rows else (0, 0, 0, 0)
    du_row = _X0 + 5 if has_du else _X0
    for k in range(n):
        wu, al, wl, d = X[_X0 + 1, k], X[_X0 + 2, k], X[_X0 + 3, k], X[_X0 + 4, k]
        r = L[Y3, k]
        _, _, r1, r2, r3 = _reference(L, k, hold, ramp, approach, tau)
        # the brake law, its slope and curvature at the estimated lower speed and its derivatives in the lower
        # angle (rows 4-9, a model with effects; FlatnessLaw.friction)
        t0, tp, tm = TQ[0, k], TQ[1, k], TQ[2, k]
        T, T1, T2 = t0, (tp - tm) / (2 * hf), (tp - 2 * t0 + tm) / hf**2
        ap, am = TQ[ap_row, k], TQ[am_row, k]
        Ta = (ap - am) / (2 * ANGLE_STEP) if angle_rows else 0.0
        Taa = (ap - 2 * t0 + am) / ANGLE_STEP**2 if angle_rows else 0.0
        Twa = TQ[pp_row, k] - TQ[pm_row, k] - TQ[mp_row, k] + TQ[mm_row, k]
        Twa = Twa / (4 * hf * ANGLE_STEP) if angle_rows else 0.0
        f = 1.0 + d
        T = f * T if scale else T + d
        T1, T2, Ta, Taa, Twa = (f * T1, f * T2, f * Ta, f * Taa, f * Twa) if scale else (T1, T2, Ta, Taa, Twa)
        rest = (wl <= w_rest) & (-kt * al < T)
        T1, T2 = (0.0 if rest else T1), (0.0 if rest else T2)
        Ta, Taa, Twa = (0.0 if rest else Ta), (0.0 if rest else Taa), (0.0 if rest else Twa)
        a = 0.0 if rest else (-kt * al - T) / Jl
        j = 0.0 if rest else (-kt * (wl - wu) - T1 * a - Ta * wl) / Jl
        z = L[Z, k] + dt * (wl - r) if L[TL, k] + dt > hold + ramp else L[Z, k]
        L[Z, k] = z
        v = r3 - (L[K0, k] * z + L[K1, k] * (wl - r) + L[K2, k] * (a - r1) + L[K3, k] * (j - r2))
        wu_dot = (Jl * v + kt * a + T2 * a * a + T1 * j + 2 * Twa * wl * a + Taa * wl**2 + Ta * a) / kt
        u = (Ju * wu_dot + TQ[3, k] - kt * al) / km
        U[k] = u - X[du_row, k] / km if has_du else u
    for k in range(n):  # the lags and the clock one period on
        d1, d2, d3, _, _ = _reference(L, k, hold, ramp, approach, tau)
        L[Y1, k], L[Y2, k], L[Y3, k] = L[Y1, k] + dt * d1, L[Y2, k] + dt * d2, L[Y3, k] + dt * d3
        L[TL, k] = L[TL, k] + dt


@njit(cache=True, error_model="numpy")
def clip(U, n, u_max):
    """The commands U (V) clipped to [-u_max, u_max] in place."""
    for k in range(n):
        U[k] = min(max(U[k], -u_max), u_max)


@njit(cache=True, error_model="numpy")
def model_rhs(X, C, n, dim, U, SH, Fv, J, jac):
    """The model's right-hand side Fv (dim, n) at the estimates (rows 0.. of X) under U, and with ``jac`` its
    Jacobian J (dim*dim, n, :func:`jacobian`); SH the model's rows of :func:`brake_shapes` at the estimates."""
    Ju, Jl = C[JU], C[JL]
    Tcu, dTcu, bu, dbu = C[TCU], C[DTCU], C[BU], C[DBU]
    scale, has_du = C[SCALE] > 0, C[HAS_DU] > 0
    e_rest = _shape(0.0, C[WS], C[DELTA])
    for k in range(n):
        wu, wl, d = X[_X0 + 1, k], X[_X0 + 3, k], X[_X0 + 4, k]
        Fu, Fl, mu, ml, Tsf, Tcf, bbf, e_l, awl, yu = _modes(X, C, U, SH, k, e_rest)
        tfu = _upper(abs(yu), mu, Tcu, dTcu, bu, dbu)
        tfl = ml * (Tcf + (Tsf - Tcf) * e_l + bbf * awl)
        au = (Fu - tfu) / Ju if mu != 0 else 0.0
        a_l = (Fl - tfl) / Jl if ml != 0 else 0.0
        Fv[0, k] = wu
        Fv[1, k] = au + (X[_X0 + 5, k] / Ju if has_du else 0.0)
        Fv[2, k] = wl - wu
        Fv[3, k] = a_l - (0.0 if scale else d / Jl)
        Fv[4, k] = 0.0
        if has_du:
            Fv[5, k] = 0.0
    if jac:
        jacobian(X, C, n, dim, U, SH, J)


@njit(error_model="numpy")  # LLVM inlines it: inlined by numba (inline="always") the loops stay scalar
def _modes(X, C, U, SH, k, e_rest):
    """Lane k's torques Fu, Fl (N m) besides friction, its modes mu, ml (the stick logic of resolve_modes: a disc
    slower than eps at rest unless its holding torque leaves the stick set), the brake's levels Tsf, Tcf, bbf, its
    shape e_l (e_rest: the shape at rest, :func:`_shape` at 0) and the speeds awl, yu the friction laws take."""
    eps, km, kt = C[EPS], C[KM], C[KTH]
    Tcu, dTcu = C[TCU], C[DTCU]
    Ts, Tc, bb = C[TS], C[TC], C[BB]
    z0, wu, z2, wl, d = X[_X0, k], X[_X0 + 1, k], X[_X0 + 2, k], X[_X0 + 3, k], X[_X0 + 4, k]
    f = 1.0 + d if C[SCALE] > 0 else 1.0
    Tsf, Tcf, bbf = Ts * f, Tc * f, bb * f
    alpha = (z0 + z2) - z0
    Fu = km * U[k] + kt * alpha
    Fl = 0.0 - kt * alpha
    stuck_u = abs(wu) <= eps
    stuck_l = abs(wl) <= eps
    mu = (1.0 if Fu > Tcu + dTcu else (-1.0 if Fu < -Tcu + dTcu else 0.0)) if stuck_u else _sign(wu)
    ml = (1.0 if Fl > Tsf else (-1.0 if Fl < -Tsf else 0.0)) if stuck_l else _sign(wl)
    e_l = e_rest if stuck_l else SH[0, k]  # a disc at rest
    return Fu, Fl, mu, ml, Tsf, Tcf, bbf, e_l, 0.0 if stuck_l else abs(wl), 0.0 if stuck_u else wu


@njit
def _varying(m, j):
    """True for the Jacobian's entries (m, j) that vary from lane to lane (:func:`jacobian`): the upper disc's
    acceleration in its speed and the twist, the lower's in the twist, its speed and the disturbance."""
    return (m == 1 and 1 <= j <= 2) or (m == 3 and 2 <= j <= 4)


@njit
def _jacobian_constant(C, m, j):
    """The Jacobian's entry (m, j) where it is the same in every lane (not :func:`_varying`)."""
    if (m, j) in ((0, 1), (2, 3)):
        return 1.0
    if (m, j) == (2, 1):
        return -1.0
    return 1.0 / C[JU] if C[HAS_DU] > 0 and (m, j) == (1, 5) else 0.0


@njit(cache=True, error_model="numpy")
def jacobian(X, C, n, dim, U, SH, J):
    """The right-hand side's Jacobian J (dim*dim, n) at the estimates under U, the modes held: central differences
    in the speeds, as the reference.  Only its lane-varying entries (:func:`_varying`) are stored, the rows
    :func:`observer_transition` reads (the constant ones it takes from :func:`_jacobian_constant`).  Every lane's
    entries are stored whatever its modes (0 where a mode leaves them out), so that the loops over the lanes stay
    branch-free; in two loops, the upper disc's and the lower's: one loop storing them all needs more run-time
    alias checks than LLVM's vectoriser takes."""
    h, Ju, Jl, kt = C[H], C[JU], C[JL], C[KTH]
    Tcu, dTcu, bu, dbu = C[TCU], C[DTCU], C[BU], C[DBU]
    Ts, Tc, bb = C[TS], C[TC], C[BB]
    scale = C[SCALE] > 0
    for k in range(n):  # the upper disc's entries
        wu = X[_X0 + 1, k]
        Fu, _, mu, _, _, _, _, _, _, _ = _modes(X, C, U, SH, k, 0.0)
        tp = _upper(abs(wu + h), mu, Tcu, dTcu, bu, dbu)
        tm = _upper(abs(wu - h), mu, Tcu, dTcu, bu, dbu)
        J[1 * dim + 1, k] = ((Fu - tp) / Ju - (Fu - tm) / Ju) / (2.0 * h) if mu != 0 else 0.0
        J[1 * dim + 2, k] = kt / Ju if mu != 0 else 0.0
    for k in range(n):  # the lower disc's
        wl = X[_X0 + 3, k]
        _, Fl, _, ml, Tsf, Tcf, bbf, _, _, _ = _modes(X, C, U, SH, k, 0.0)
        tp = ml * (Tcf + (Tsf - Tcf) * SH[1, k] + bbf * abs(wl + h))
        tm = ml * (Tcf + (Tsf - Tcf) * SH[2, k] + bbf * abs(wl - h))
        J[3 * dim + 2, k] = -kt / Jl if ml != 0 else 0.0
        J[3 * dim + 3, k] = ((Fl - tp) / Jl - (Fl - tm) / Jl) / (2.0 * h) if ml != 0 else 0.0
        level = -ml * (Tc + (Ts - Tc) * SH[0, k] + bb * abs(wl)) / Jl
        J[3 * dim + 4, k] = (level if ml != 0 else 0.0) if scale else -1.0 / Jl


@njit(cache=True, error_model="numpy")
def predict_mean(X, C, n, nc, g, Fv, W):
    """x[:nc] += Gamma f, Gamma (nc x nc) at C[g:], f in the rows Fv (nc, n).  W: work rows (>= nc)."""
    for i in range(nc):  # each sum starts with its first term (0 + x is x)
        g0 = C[g + i * nc]
        for k in range(n):
            W[i, k] = g0 * Fv[0, k]
        for m in range(1, nc):
            gi = C[g + i * nc + m]
            for k in range(n):
                W[i, k] += gi * Fv[m, k]
    for i in range(nc):
        for k in range(n):
            X[_X0 + i, k] += W[i, k]


@njit(cache=True, error_model="numpy")
def observer_transition(C, n, dim, mats, J, F):
    """F = Ad + Gamma (J - Ac) into the rows F (dim*dim, n) for J of :func:`jacobian` (Ad, Gamma, Ac dim x dim at
    C[mats:]): its part from the constant entries once per period, Ad + Gamma (Jc - Ac) (Jc: J with 0 at the
    lane-varying entries), then Gamma's columns 1 and 3 times the lane-varying entries, rows 1 and 3 of J (the
    sums of :func:`predict_covariance` reordered: a few passes over the lanes instead of dim^3)."""
    dd = dim * dim
    Ad, G, Ac = mats, mats + dd, mats + 2 * dd
    for i in range(dim):
        g1, g3 = C[G + i * dim + 1], C[G + i * dim + 3]
        for j in range(dim):
            base = C[Ad + i * dim + j]
            for m in range(dim):
                jc = 0.0 if _varying(m, j) else _jacobian_constant(C, m, j)
                base += C[G + i * dim + m] * (jc - C[Ac + m * dim + j])
            row, j1, j3 = F[i * dim + j], J[1 * dim + j], J[3 * dim + j]
            if _varying(1, j) and _varying(3, j):
                for k in range(n):
                    row[k] = base + g1 * j1[k] + g3 * j3[k]
            elif _varying(1, j):
                for k in range(n):
                    row[k] = base + g1 * j1[k]
            elif _varying(3, j):
                for k in range(n):
                    row[k] = base + g3 * j3[k]
            else:
                row[:n] = base


@njit(cache=True, error_model="numpy")
def covariance_products(X, C, n, dim, p0, qd, W):
    """P = F P F' + Qd (covariance from row p0, Qd dim x dim at C[qd:]) with F in the work rows W[0:dim^2]; the
    product F P into W[dim^2:2 dim^2]."""
    if dim == 5:
        return _products_5(X, C, n, p0, qd, W)
    dd = dim * dim
    for i in range(dim):  # F P into W[dd:2dd]; each sum starts with its first term (0 + x is x)
        for j in range(dim):
            row, f, p = W[dd + i * dim + j], W[i * dim], X[p0 + j]
            for k in range(n):
                row[k] = f[k] * p[k]
            for m in range(1, dim):
                for k in range(n):
                    W[dd + i * dim + j, k] += W[i * dim + m, k] * X[p0 + m * dim + j, k]
    for i in range(dim):  # (F P) F' + Qd, the lanes innermost (vectorised); the symmetric half mirrored
        for j in range(i, dim):
            q = C[qd + i * dim + j]
            row, a, b = X[p0 + i * dim + j], W[dd + i * dim], W[j * dim]
            for k in range(n):
                row[k] = q + a[k] * b[k]
            for m in range(1, dim):
                a = W[dd + i * dim + m]
                b = W[j * dim + m]
                for k in range(n):
                    row[k] += a[k] * b[k]
            if j != i:
                X[p0 + j * dim + i, :n] = row[:n]


@njit(cache=True, error_model="numpy")
def _products_5(X, C, n, p0, qd, W):
    """:func:`covariance_products` of a filter of 5 states (the base model's): each entry's five products summed in
    one pass over the lanes, in the same order (the same floats), a third fewer loads and stores."""
    for i in range(5):  # F P into W[25:50]
        f0, f1, f2, f3, f4 = W[i * 5], W[i * 5 + 1], W[i * 5 + 2], W[i * 5 + 3], W[i * 5 + 4]
        for j in range(5):
            q0, q1, q2, q3, q4 = X[p0 + j], X[p0 + 5 + j], X[p0 + 10 + j], X[p0 + 15 + j], X[p0 + 20 + j]
            row = W[25 + i * 5 + j]
            for k in range(n):
                row[k] = f0[k] * q0[k] + f1[k] * q1[k] + f2[k] * q2[k] + f3[k] * q3[k] + f4[k] * q4[k]
    for i in range(5):  # (F P) F' + Qd; the symmetric half mirrored
        a0, a1, a2, a3, a4 = W[25 + i * 5], W[26 + i * 5], W[27 + i * 5], W[28 + i * 5], W[29 + i * 5]
        for j in range(i, 5):
            b0, b1, b2, b3, b4 = W[j * 5], W[j * 5 + 1], W[j * 5 + 2], W[j * 5 + 3], W[j * 5 + 4]
            q = C[qd + i * 5 + j]
            row = X[p0 + i * 5 + j]
            for k in range(n):
                row[k] = q + a0[k] * b0[k] + a1[k] * b1[k] + a2[k] * b2[k] + a3[k] * b3[k] + a4[k] * b4[k]
            if j != i:
                X[p0 + j * 5 + i, :n] = row[:n]


@njit(cache=True, error_model="numpy")
def predict_covariance(X, C, n, dim, nc, p0, mats, J, W):
    """P = F P F' + Qd (covariance from row p0), F = Ad + Gamma (J - Ac) on the first nc rows and columns (Ad, Qd
    dim x dim; Gamma, Ac nc x nc: at C[mats:] in the order Ad, Gamma, Ac, Qd; J (nc^2, n) the right-hand side's
    Jacobian at the estimates).  W: work rows (>= 2 dim^2)."""
    dd = dim * dim
    Ad, G, Ac = mats, mats + dd, mats + dd + nc * nc
    Qd = Ac + nc * nc
    for i in range(dim):  # F into W[0:dd]
        for j in range(dim):
            for k in range(n):
                W[i * dim + j, k] = C[Ad + i * dim + j]
            if i >= nc or j >= nc:
                continue
            for m in range(nc):
                g = C[G + i * nc + m]
                if g != 0.0:
                    a = C[Ac + m * nc + j]
                    for k in range(n):
                        W[i * dim + j, k] += g * (J[m * nc + j, k] - a)
    covariance_products(X, C, n, dim, p0, Qd, W)


@njit(LAW_SIGNATURE, cache=True)
def observer_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the observer controller for every lane: update, law, clip, predict (module doc)."""
    n = U.size
    dim = int(C[DIM])
    W = X[_W0 : _W0 + 2 * dim * dim + dim]
    Fv = X[_F0 : _F0 + dim]
    J = X[_J0 : _J0 + dim * dim]
    SH = X[_S0 : _S0 + 6]
    TQ = X[_T0 : _T0 + 4]
    update(M, X, C[R], n, dim, _P0, W)
    wl = X[_X0 + 3]
    brake_shapes(wl, C, n, SH)
    base_torques(X, C, n, SH, TQ)
    flatness_law(M, X, X[_L0 : _L0 + len(ROWS)], C, n, U, TQ)
    clip(U, n, C[U_MAX])
    model_rhs(X, C, n, dim, U, SH[3:6], Fv, J, True)
    predict_mean(X, C, n, dim, _MAT0 + dim * dim, Fv, W)
    observer_transition(C, n, dim, _MAT0, J, W)
    covariance_products(X, C, n, dim, _P0, _MAT0 + 3 * dim * dim, W)


def filter_settled(c, dim: int, max_dim: int) -> bool:
    """True when the compiled filters run the model-based controller c (reset) as its ``act`` does: no ``descent``
    fallback, the nominal brake law, no Measurement effect on the motor angle and at most ``max_dim`` states."""
    mdl = c.model
    return c._descent is None and mdl.friction_known and not mdl.reads_effects and mdl.Ad.shape[0] == dim <= max_dim


def plain_model(c) -> bool:
    """True when the controller c is built on the base model of its parameters: no effect, delay, lag or input map."""
    mdl = c.model
    return (
        not c.effects.composition.effects
        and mdl.line_index < 0
        and mdl.lag_index < 0
        and not mdl.compensates
        and np.array_equal(mdl.dynamics.vector, c.params.to_vector())
    )


def law_rows(c, L: np.ndarray) -> None:
    """The flatness law's rows L (:data:`ROWS`, n) from the reset :class:`controllers.observer.ObserverController` c."""
    law = c.law
    L[Y1 : Y3 + 1] = law.y
    L[Z], L[TL], L[TARGET], L[LOW] = law.z, law.t, law.target, law.low
    L[K0 : K3 + 1] = np.broadcast_to(law.K, (c.n, 4)).T
    L[SETTLE], L[INTEG], L[THETA0], L[TINT] = c._settle, c._integrating, c._theta0, c._t_int


def observer_constants(c, dim: int) -> np.ndarray:
    """The values of :data:`CONSTANTS` of the reset :class:`controllers.observer.ObserverController` c."""
    mdl, law, p = c.model, c.law, c.params
    values = dict(
        dt=c.dt, r=mdl.R[0, 0], eps=mdl.dynamics.eps, h=1e-5, Ju=p.Ju, Jl=p.Jl, km=p.km, kth=p.ktheta,
        Tcu=p.Tcu, dTcu=p.dTcu, bu=p.bu, dbu=p.dbu, Ts=p.Ts, Tc=p.Tc, ws=p.ws, delta=p.delta, bb=p.bb,
        tau=law.tau, w_rest=law.w_rest, hf=law.h, hold=law.hold, ramp=law.ramp, approach=law.approach,
        u_max=c.u_max, scale=float(law.scale), has_du=float(mdl.has_du),
        trim_gain=c.angle_gain if c.angle_integral else 0.0, trim_band=TRIM_BAND, trim_clip=TRIM_CLIP, dim=float(dim),
    )  # fmt: skip
    return np.array([float(values[k]) for k in CONSTANTS])


def observer_law(c):
    """The compiled law of an :class:`controllers.observer.ObserverController` after its reset, or None.

    None when its settings need what this compiled filter does not run: a model with effects
    (:mod:`controllers.compiled.model_law` runs those), the ``descent`` fallback for some targets.

    Parameters
    ----------
    c : ObserverController
        The controller, reset.

    Returns
    -------
    controllers.compiled.CompiledLaw or None
        The law with its state (the filter's estimates and covariances, the law's lags, integral and clock)
        and constants (:data:`CONSTANTS`, then the filter's matrices).
    """
    from . import CompiledLaw

    mdl, law = c.model, c.law
    dim = mdl.nc
    base_law = law.brake is None and law.upper is None and law.scale == mdl.dynamics.scale
    if not (plain_model(c) and filter_settled(c, dim, MAX_DIM) and not mdl.reads_effects and base_law):
        return None
    n = c.n
    X = np.zeros((N_ROWS, n))
    X[_X0 : _X0 + dim] = c.observer.x
    X[_P0 : _P0 + dim * dim] = c.observer.P.reshape(n, dim * dim).T
    law_rows(c, X[_L0 : _L0 + len(ROWS)])
    C = np.concatenate([observer_constants(c, dim)] + [np.ravel(a) for a in (mdl.Ad, mdl.gamma_new, mdl.Ac, mdl.Qd)])
    return CompiledLaw(observer_step, np.ascontiguousarray(X), np.ascontiguousarray(C, dtype=np.float64))
