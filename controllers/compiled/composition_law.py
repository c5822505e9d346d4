"""The model-based laws on a composition's compiled model: a kernel client template, compiled once per composition.

Not imported as it stands: :func:`drillgym.effects.foreign_client.foreign_client` writes a copy of this file into a
composition's generated package with its ``drillgym.kernels.*`` imports pointing there (the composition's
``state_derivative``, ``resolve_modes`` and ``hk_rhs``), named after a digest of the sources it imports, so numba
compiles it once and every later process loads it from the cache (``cache=True``), where closures over the
composition's functions were compiled again in every process (about 9 s for the observer and the lqg-2enc on a
model with a lag, a delay and position friction, on 2 cores).  :func:`controllers.dynamics.model_kernels` and
:func:`controllers.compiled.model_law.law_step` load it.

The model's functions (:class:`controllers.dynamics.ModelDynamics`'s), at an estimator's state
``z = (theta_u, omega_u, alpha, omega_l, d, [du], effect states ...)``:

* ``evaluate``: dz/dt, the modes resolved by the stick logic or held; ``slipping``: dz/dt and the voltage at the
  motor with the discs slipping at given speeds; ``lane_jacobian``: the central-difference Jacobians; ``settled``:
  the voltage at the motor for a command held until the lags settled; ``rhs``, ``jac``, ``volt``: the same over
  rows;

and the laws' steps of :mod:`controllers.compiled.model_law` (its module doc): ``observer_step``, ``lqg_step``,
``two_encoder_step``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from controllers.compiled import lqg_law as lq
from controllers.compiled import observer_law as ob
from controllers.compiled import two_encoder_law as te
from controllers.compiled.model_law import (
    COMP,
    DSTEPS,
    E0,
    HAS_OLD,
    IDU,
    NC,
    NLINE,
    OBSERVER_TORQUES,
    OGN,
    OGO,
    OH,
    OHH,
    OKF,
    OLC,
    OLT,
    OMATS,
    OP,
    OTAIL,
    command,
    lqg_rows,
    observer_rows,
    shift_line,
)
from controllers.flatness import ANGLE_STEP
from drillgym.configurations import Configuration
from drillgym.kernels.hooks import N_STATE, hk_rhs
from drillgym.kernels.model import resolve_modes, state_derivative
from drillgym.params import IDX

NY = N_STATE
NE = NY - 8
CFG = int(Configuration.TORSIONAL)
_Ts, _Tc, _bb, _Ju, _Jl, _KT, _KM = IDX.Ts, IDX.Tc, IDX.bb, IDX.Ju, IDX.Jl, IDX.ktheta, IDX.km


@njit(cache=True)
def _state(z, e0, y):  # pragma: no cover - compiled
    """The composition's state y at an estimator's state z: the discs' angles and speeds, the effect states (from
    row e0 of z); the lateral states 0."""
    for i in range(NY):
        y[i] = 0.0
    y[0] = z[0]
    y[1] = z[0] + z[2]
    y[2] = z[1]
    y[3] = z[3]
    for j in range(NE):
        y[8 + j] = z[e0 + j]


@njit(cache=True)
def evaluate(z, v, p, e0, idu, scale, eps, freeze, mode_in, out, y, pp, dy, fric, mode):  # pragma: no cover
    """dz/dt into ``out`` at the state z (nz,) under the command v (V) entering the Input chain: the modes resolved
    (the stick logic) or, with ``freeze``, ``mode_in``; y ... mode: work arrays."""
    _state(z, e0, y)
    for i in range(p.size):
        pp[i] = p[i]
    if scale:
        f = 1.0 + z[4]
        pp[_Ts] *= f
        pp[_Tc] *= f
        pp[_bb] *= f
    if freeze:
        mode[0] = mode_in[0]
        mode[1] = mode_in[1]
    else:
        mode[0] = 0 if abs(z[1]) <= eps else (1 if z[1] > 0 else -1)
        mode[1] = 0 if abs(z[3]) <= eps else (1 if z[3] > 0 else -1)
    if mode[0] == 0:
        y[2] = 0.0
    if mode[1] == 0:
        y[3] = 0.0
    if not freeze and (mode[0] == 0 or mode[1] == 0):
        resolve_modes(0.0, y, mode, v, pp, CFG, dy, fric)
    else:
        state_derivative(0.0, y, mode, v, pp, CFG, 0.0, dy, fric)
    for i in range(out.size):
        out[i] = 0.0
    out[0] = z[1]
    out[1] = dy[2]
    out[2] = z[3] - z[1]
    out[3] = dy[3]
    if not scale:
        out[3] -= z[4] / pp[_Jl]
    if idu >= 0:
        out[1] += z[idu] / pp[_Ju]
    for j in range(NE):
        out[e0 + j] = dy[8 + j]


@njit(cache=True)
def slipping(z, v, wu, wl, p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in):  # pragma: no cover
    """dz/dt into ``out`` at z with the discs slipping at wu, wl (rad/s, set in z; modes held at their signs) under
    the command v (V); returns the voltage at the motor (V)."""
    z[1] = wu
    z[3] = wl
    mode_in[0] = 1 if wu >= 0 else -1
    mode_in[1] = 1 if wl >= 0 else -1
    evaluate(z, v, p, e0, idu, scale, eps, True, mode_in, out, y, pp, dy, fric, mode)
    return hk_rhs(0.0, v, y, pp, CFG, d2)[0]


@njit(cache=True)
def rhs(Z, V, P, e0, idu, scale, eps, WU, WL, force, OUT, VOLT):  # pragma: no cover
    """dz/dt of every row of Z and the voltage at the motor (V); with ``force`` the discs slip at speeds WU, WL
    (modes held)."""
    n, nz = Z.shape
    y, pp, dy, d2 = np.zeros(NY), np.zeros(P.shape[1]), np.zeros(NY), np.zeros(NY)
    fric, mode, mode_in = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
    z = np.zeros(nz)
    for k in range(n):
        for i in range(nz):
            z[i] = Z[k, i]
        if force:
            VOLT[k] = slipping(z, V[k], WU[k], WL[k], P[k], e0, idu, scale, eps, OUT[k], y, pp, dy, d2, fric, mode,
                               mode_in)  # fmt: skip
        else:
            evaluate(z, V[k], P[k], e0, idu, scale, eps, False, mode_in, OUT[k], y, pp, dy, fric, mode)
            VOLT[k] = hk_rhs(0.0, V[k], y, pp, CFG, d2)[0]


@njit(cache=True)
def lane_jacobian(
    z, v, p, e0, idu, scale, eps, H, with_b, J, B, f0, fp, fm, y, pp, dy, fric, mode, mode0
):  # pragma: no cover
    """Central-difference Jacobians at the state z (nz,; restored): J = df/dz (nz, nz) and, with ``with_b``,
    B = df/dv (nz,), the modes of (z, v) held; f0 receives f(z, v); H the steps (nz + 1,)."""
    nz = z.size
    evaluate(z, v, p, e0, idu, scale, eps, False, mode0, f0, y, pp, dy, fric, mode0)
    for c in range(nz + 1 if with_b else nz):
        h = H[c]
        if c < nz:
            zc = z[c]
            z[c] = zc + h
            evaluate(z, v, p, e0, idu, scale, eps, True, mode0, fp, y, pp, dy, fric, mode)
            z[c] = zc - h
            evaluate(z, v, p, e0, idu, scale, eps, True, mode0, fm, y, pp, dy, fric, mode)
            z[c] = zc
            for i in range(nz):
                J[i, c] = (fp[i] - fm[i]) / (2.0 * h)
        else:
            evaluate(z, v + h, p, e0, idu, scale, eps, True, mode0, fp, y, pp, dy, fric, mode)
            evaluate(z, v - h, p, e0, idu, scale, eps, True, mode0, fm, y, pp, dy, fric, mode)
            for i in range(nz):
                B[i] = (fp[i] - fm[i]) / (2.0 * h)


@njit(cache=True)
def jac(Z, V, P, e0, idu, scale, eps, H, J, B):  # pragma: no cover
    """Central-difference Jacobians J = df/dz (n, nz, nz) and B = df/dv (n, nz), the modes held."""
    n, nz = Z.shape
    y, pp, dy = np.zeros(NY), np.zeros(P.shape[1]), np.zeros(NY)
    fric, mode, mode0 = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
    z = np.zeros(nz)
    f0, fp, fm = np.zeros(nz), np.zeros(nz), np.zeros(nz)
    for k in range(n):
        for i in range(nz):
            z[i] = Z[k, i]
        lane_jacobian(z, V[k], P[k], e0, idu, scale, eps, H, True, J[k], B[k], f0, fp, fm, y, pp, dy, fric, mode,
                      mode0)  # fmt: skip


@njit(cache=True)
def settled(z, u, p, e0, y, dy, lag_cols, lag_tau):  # pragma: no cover
    """The voltage at the motor (V) for the command u held until the lags settled, at state z; ``lag_cols`` the
    declared lag states' columns after the 8 mechanical ones, ``lag_tau`` their time constants' parameter indices
    (:func:`controllers.dynamics.lag_arrays`)."""
    _state(z, e0, y)
    for j in range(lag_cols.size):
        y[8 + lag_cols[j]] = u
    for _ in range(lag_cols.size + 1):  # each lag at the voltage entering it (the chain in order)
        hk_rhs(0.0, u, y, p, CFG, dy)
        for j in range(lag_cols.size):
            y[8 + lag_cols[j]] += p[lag_tau[j]] * dy[8 + lag_cols[j]]
    return hk_rhs(0.0, u, y, p, CFG, dy)[0]


@njit(cache=True)
def volt(Z, U, P, e0, OUT, lag_cols, lag_tau):  # pragma: no cover
    """:func:`settled` of every row of Z under the commands U (V) into OUT."""
    y, dy = np.zeros(NY), np.zeros(NY)
    for k in range(Z.shape[0]):
        OUT[k] = settled(Z[k], U[k], P[k], e0, y, dy, lag_cols, lag_tau)


# ---------------------------------------------------------------------------------------------- the laws' steps
@njit(cache=True)
def _load(X, k, C, z):  # pragma: no cover
    """The estimate of lane k with d = du = 0 into z (the model's torques at its own brake level)."""
    for i in range(z.size):
        z[i] = X[i, k]
    z[4] = 0.0
    if C[IDU] >= 0:
        z[int(C[IDU])] = 0.0


@njit(cache=True)
def torques(X, C, n, TQ, nlow, REF):  # pragma: no cover
    """The model's torques (N m) at the estimates into TQ: for the observer (nlow 3) the brake law at the law's
    speed ww and ww +- step, for the lqg (nlow 1) at the estimated lower speed (at ``slip_eps`` while it rests); then
    the upper disc's at the estimated upper speed (observer) or at REF (lqg, rad/s); for the observer then the brake
    law at the lower angle moved by +- ANGLE_STEP at ww, ww + step, ww - step, ww + step, ww - step (signs +, -, +,
    +, -, -: its derivatives in the angle, :meth:`FlatnessLaw.friction`)."""
    nz, e0, idu = int(C[NC]), int(C[E0]), int(C[IDU])
    p = C[int(C[OP]) : int(C[OH])]
    scale, eps, hf = C[ob.SCALE] > 0, C[ob.EPS], C[ob.HF]
    z, out = np.zeros(nz), np.zeros(nz)
    y, pp, dy, d2 = np.zeros(NY), np.zeros(p.size), np.zeros(NY), np.zeros(NY)
    fric, mode, mode_in = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
    for k in range(n):
        _load(X, k, C, z)
        wu, al, wl = z[1], z[2], z[3]
        if nlow == 3:
            ww = max(wl, C[ob.W_REST] + hf)
            speeds = (ww, ww + hf, ww - hf)
        else:
            seps = C[lq.SLIP_EPS]
            speeds = (wl if abs(wl) > seps else seps, 0.0, 0.0)
        for j in range(nlow):
            slipping(z, 0.0, wu, speeds[j], p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
            TQ[j, k] = -p[_KT] * al - p[_Jl] * out[3]
        w = (1e-9 if wu == 0 else wu) if nlow == 3 else REF[k]
        vm = slipping(z, 0.0, w, wl, p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
        TQ[nlow, k] = p[_KM] * vm + p[_KT] * al - p[_Ju] * out[1]
        if nlow == 3:  # the lower angle moved, the twist kept: the motor angle moved
            th = z[0]
            for j in range(6):
                z[0] = th + (ANGLE_STEP if j == 0 or j == 2 or j == 3 else -ANGLE_STEP)
                sp = speeds[0] if j < 2 else (speeds[1] if j == 2 or j == 4 else speeds[2])
                slipping(z, 0.0, wu, sp, p, e0, idu, scale, eps, out, y, pp, dy, d2, fric, mode, mode_in)
                TQ[4 + j, k] = -p[_KT] * al - p[_Jl] * out[3]
            z[0] = th


@njit(cache=True)
def linearise(X, C, n, U, Fn, Fo, J, with_jacobian):  # pragma: no cover
    """f at the estimates under the newer command (U or the line's) into Fn (nc, n), under the older one into Fo
    when a fractional delay splits the period, and with ``with_jacobian`` the Jacobian df/dz at the newer into J
    (nc^2, n; the modes held)."""
    nz, e0, idu = int(C[NC]), int(C[E0]), int(C[IDU])
    ds, nline = int(C[DSTEPS]), int(C[NLINE])
    p = C[int(C[OP]) : int(C[OH])]
    H = C[int(C[OH]) : int(C[OH]) + nz + 1]
    scale, eps = C[ob.SCALE] > 0, C[ob.EPS]
    z, f0, fp, fm, Jk, Bk = np.zeros(nz), np.zeros(nz), np.zeros(nz), np.zeros(nz), np.zeros((nz, nz)), np.zeros(nz)
    y, pp, dy = np.zeros(NY), np.zeros(p.size), np.zeros(NY)
    fric, mode, mode0 = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
    for k in range(n):
        for i in range(nz):
            z[i] = X[i, k]
        new = U[k] if ds == 0 else X[nz + ds - 1, k]
        if with_jacobian:
            lane_jacobian(z, new, p, e0, idu, scale, eps, H, False, Jk, Bk, f0, fp, fm, y, pp, dy, fric, mode, mode0)
            for i in range(nz):
                for c in range(nz):
                    J[i * nz + c, k] = Jk[i, c]
        else:
            evaluate(z, new, p, e0, idu, scale, eps, False, mode0, f0, y, pp, dy, fric, mode)
        for i in range(nz):
            Fn[i, k] = f0[i]
        if C[HAS_OLD] > 0:
            old = X[nz + ds, k] if ds < nline else new
            evaluate(z, old, p, e0, idu, scale, eps, False, mode0, fp, y, pp, dy, fric, mode)
            for i in range(nz):
                Fo[i, k] = fp[i]


@njit(cache=True)
def _predict(X, C, n, U, Fn, Fo, W):  # pragma: no cover
    """The mean one period on: x[:nc] += Gamma_new f(new) (+ Gamma_old f(old)), the line shifted."""
    nc, dim = int(C[NC]), int(C[ob.DIM])
    ob.predict_mean(X, C, n, nc, int(C[OGN]), Fn, W)
    if C[HAS_OLD] > 0:
        ob.predict_mean(X, C, n, nc, int(C[OGO]), Fo, W)
    shift_line(X, n, nc, dim, U)


@njit(cache=True)
def observer_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the observer for every lane: update, law, inversion, clip, predict."""
    n, dim, nc = U.size, int(C[ob.DIM]), int(C[NC])
    p0, l0, w0, fn, fo, j0, t0, _ = observer_rows(dim, nc)
    ob.update(M, X, C[ob.R], n, dim, p0, X[w0:fn])
    torques(X, C, n, X[t0 : t0 + OBSERVER_TORQUES], 3, X[t0])
    ob.flatness_law(M, X, X[l0:w0], C, n, U, X[t0 : t0 + OBSERVER_TORQUES])
    command(U, C, n)
    linearise(X, C, n, U, X[fn:fo], X[fo:j0], X[j0:t0], True)
    ob.predict_covariance(X, C, n, dim, nc, p0, int(C[OMATS]), X[j0:t0], X[w0:fn])
    _predict(X, C, n, U, X[fn:fo], X[fo:j0], X[w0:fn])


@njit(cache=True)
def lqg_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the lqg for every lane: correct, torques, feedback, inversion, clip, predict."""
    g0, fn, fo, w0, t0, r0, _ = lqg_rows(int(C[ob.DIM]), int(C[NC]))
    lq.correct(M, X, C, U.size, int(C[ob.DIM]), int(C[OKF]), int(C[OHH]))
    lq.clock(M, X[g0:fn], C, U.size, X[r0])
    torques(X, C, U.size, X[t0:r0], 1, X[r0])
    lq.feedback(X, X[g0:fn], C, U.size, U, X[t0:r0], X[r0])
    command(U, C, U.size)
    linearise(X, C, U.size, U, X[fn:fo], X[fo:w0], X[fn:fo], False)
    _predict(X, C, U.size, U, X[fn:fo], X[fo:w0], X[w0:t0])


@njit(cache=True)
def _equilibrium(X, C, T, n, EQ):  # pragma: no cover
    """The winding (rad) and the voltage at the motor (V) of the model's slip equilibrium at each lane's reference
    speed near its estimated angles into EQ (TwoEncoderLQG._model_equilibrium); T the law's own constants."""
    nz, e0, eps = int(C[NC]), int(C[E0]), C[ob.EPS]
    p = C[int(C[OP]) : int(C[OH])]
    z, out = np.zeros(nz), np.zeros(nz)
    y, pp, dy, d2 = np.zeros(NY), np.zeros(p.size), np.zeros(NY), np.zeros(NY)
    fric, mode, mode_in = np.zeros(2), np.zeros(2, np.int64), np.zeros(2, np.int64)
    for k in range(n):
        r = max(X[te.REF, k], T[te.GSTEP])
        z[:] = 0.0
        z[0], z[2] = X[0, k], X[2, k]
        slipping(z, 0.0, r, r, p, e0, -1, False, eps, out, y, pp, dy, d2, fric, mode, mode_in)
        a = -(-p[_KT] * z[2] - p[_Jl] * out[3]) / C[ob.KTH]
        z[2] = a
        vm = slipping(z, 0.0, r, r, p, e0, -1, False, eps, out, y, pp, dy, d2, fric, mode, mode_in)
        EQ[0, k] = a
        EQ[1, k] = (p[_KM] * vm + p[_KT] * a - p[_Ju] * out[1] - C[ob.KTH] * a) / C[ob.KM]


@njit(cache=True)
def _motor(C, n, U, V, XD, EV):  # pragma: no cover
    """The voltage at the motor (V) the commands U (V) give once the lags settled, at the corrected estimates."""
    nz, e0 = int(C[NC]), int(C[E0])
    p = C[int(C[OP]) : int(C[OH])]
    lag_cols = C[int(C[OLC]) : int(C[OLT])].astype(np.int64)
    lag_tau = C[int(C[OLT]) : int(C[OLT]) + lag_cols.size].astype(np.int64)
    z, y, dy = np.zeros(nz), np.zeros(NY), np.zeros(NY)
    for k in range(n):
        if C[COMP] == 0:
            V[k] = U[k]
            continue
        z[:] = 0.0
        for i in range(4):
            z[i] = XD[i, k] + EV[i, k]
        V[k] = settled(z, U[k], p, e0, y, dy, lag_cols, lag_tau)


@njit(cache=True)
def two_encoder_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the lqg-2enc for every lane: equilibrium, correction, inversion, clip, prediction."""
    n, T = U.size, C[int(C[OTAIL]) :]
    EQ, XD, EV = (
        X[te.EQ_ROW : te.EQ_ROW + 2],
        X[te.XD_ROW : te.XD_ROW + te.MAX_NX],
        X[te.EV_ROW : te.EV_ROW + te.MAX_NX],
    )
    _equilibrium(X, C, T, n, EQ)
    te.correct(M, X, T, n, U, EQ, XD, EV)
    command(U, C, n)
    _motor(C, n, U, X[te.V_ROW], XD, EV)
    te.predict(X, T, n, X[te.V_ROW], EQ, XD, EV)
