"""The ``lqg`` controller's law compiled: stationary Kalman gain on the motor angle, LQR about an equilibrium.

What :meth:`controllers.observer.LQGController.act` computes each period, for every lane, on a model without
effects: the filter's correction with the stationary gain ``Kf`` and the measured motor angle, the estimated lower
friction (the brake law at the estimated speed, its level error ``d`` added or scaled; the holding torque at
rest), the equilibrium it defines (winding alpha* = -d^ / k_theta, voltage u* of the upper disc's friction at the
target), the LQR feedback on the errors of (alpha, omega_u, omega_l), the optional integral on the measured motor
angle (``outer_gain``), the clip, then the mean's prediction with the applied voltage (the exponential Euler step
of :meth:`controllers.kalman.DisturbanceModel.predict_mean`: x + Gamma f(x, u), the right-hand side of
:func:`controllers.compiled.observer_law.model_rhs`).

State rows (per lane): the estimates (dim), the LQR gains on (alpha, omega_u, omega_l), the motor angle when the
integral starts (rad), the time since reset (s), the target (rad/s), then work rows (the right-hand side, the brake
law's shape).
Constants: :data:`controllers.compiled.observer_law.CONSTANTS` (the model's parameters; the observer's law
options unused), then :data:`EXTRA`, then Gamma (dim x dim), Kf (dim) and H (dim), row-major.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE, M_TU

from .observer_law import (
    BB,
    CONSTANTS,
    DELTA,
    DIM,
    KM,
    KTH,
    MAX_DIM,
    SCALE,
    TC,
    TS,
    U_MAX,
    WS,
    _shape,
    clip,
    filter_settled,
    model_rhs,
    plain_model,
    predict_mean,
)

__all__ = ["lqg_step", "lqg_law", "EXTRA"]

EXTRA = ("outer_gain", "outer_start", "upper_coulomb", "upper_damping", "slip_eps", "dt_lqg")
"""Constants after the observer's: integral gain (1/s), its start (s), Tcu + dTcu (N m), bu + dbu (N m s/rad), the
speed below which the lower disc is taken at rest for the friction estimate (rad/s), the period (s)."""
OUTER_GAIN, OUTER_START, UCOUL, UDAMP, SLIP_EPS, DT_LQG = range(len(CONSTANTS), len(CONSTANTS) + len(EXTRA))
_MAT0 = len(CONSTANTS) + len(EXTRA)  # then Gamma (dim x dim), Kf (dim), H (dim)

_KG0 = MAX_DIM  # the law's rows (:data:`ROWS`), then work: the right-hand side (MAX_DIM rows), the shape at
_F0 = _KG0 + 6  # |omega_l|, the torques (:func:`base_torques`), the reference speed and the mean's increments
_SH = _F0 + MAX_DIM
_TQ = _SH + 1
_REF = _TQ + 2
_W = _REF + 1
N_ROWS = _W + MAX_DIM
ROWS = ("k_alpha", "k_omega_u", "k_omega_l", "theta0", "time", "target")
"""The law's rows: the LQR gains on (alpha, omega_u, omega_l), the motor angle when the integral starts (rad), the
time since reset (s), the target (rad/s)."""
KG, THETA0, TIME, TARGET = 0, 3, 4, 5


@njit(cache=True, error_model="numpy")
def correct(M, X, C, n, dim, kf, hh):
    """x += Kf (theta_u - H x): the stationary filter's correction with the measured motor angles (Kf, H (dim,) at
    C[kf:], C[hh:])."""
    for k in range(n):
        y = 0.0
        for j in range(dim):
            y += C[hh + j] * X[j, k]
        innov = M[M_TU, k] - y
        for i in range(dim):
            X[i, k] += C[kf + i] * innov


@njit(cache=True, error_model="numpy")
def _shapes(X, C, n, a):
    """The brake law's shape at the estimated |omega_l| into row a (vectorises)."""
    ws, delta = C[WS], C[DELTA]
    wl_ = X[3]
    for k in range(n):
        a[k] = _shape(abs(wl_[k]), ws, delta)


@njit(cache=True, error_model="numpy")
def clock(M, G, C, n, REF):
    """The clock advanced and the reference speed (rad/s) into REF: the target, moved by the integral on the
    measured motor angle (``outer_gain``); G the law's rows (:data:`ROWS`)."""
    g, t0 = C[OUTER_GAIN], C[OUTER_START]
    for k in range(n):
        t = G[TIME, k] + C[DT_LQG]
        G[TIME, k] = t
        ref = G[TARGET, k]
        if g > 0:  # integral action on the measured motor angle
            th = M[M_TU, k]
            if t <= t0:
                G[THETA0, k] = th
            z = th - G[THETA0, k] - ref * max(t - t0, 0.0)
            ref = min(max(ref - g * z, 0.5 * ref), 1.5 * ref)
        REF[k] = ref


@njit(cache=True, error_model="numpy")
def base_torques(X, C, n, SH, REF, TQ):
    """The torques of the model without effects (N m) into TQ: the brake law at the estimated lower speed (at
    ``slip_eps`` while it rests; SH its shape), the upper disc's friction at the reference speed REF."""
    Ts, Tc, bb, ws, delta, eps = C[TS], C[TC], C[BB], C[WS], C[DELTA], C[SLIP_EPS]
    shape_eps = _shape(eps, ws, delta)
    for k in range(n):
        wl = X[3, k]
        slip = abs(wl) > eps
        w = wl if slip else eps
        e = SH[0, k] if slip else shape_eps
        TQ[0, k] = (1.0 if w > 0 else (-1.0 if w < 0 else 0.0)) * (Tc + (Ts - Tc) * e + bb * abs(w))
        TQ[1, k] = C[UCOUL] + C[UDAMP] * REF[k]


@njit(cache=True, error_model="numpy")
def feedback(X, G, C, n, U, TQ, REF):
    """The LQR voltage (V, not clipped) about the equilibrium the friction estimate defines into U; TQ the brake
    law at the estimated lower speed and the upper disc's torque at the reference speed REF (N m)."""
    kt, km, eps = C[KTH], C[KM], C[SLIP_EPS]
    scale = C[SCALE] > 0
    for k in range(n):
        al, wu, wl, d = X[2, k], X[1, k], X[3, k], X[4, k]
        T = TQ[0, k]
        T = T * (1.0 + d) if scale else T + d
        d_hat = T if abs(wl) > eps else -kt * al
        alpha_star = -d_hat / kt
        ref = REF[k]
        u_star = (TQ[1, k] + d_hat) / km
        fb = G[KG, k] * (al - alpha_star) + G[KG + 1, k] * (wu - ref) + G[KG + 2, k] * (wl - ref)
        U[k] = u_star - fb


@njit(LAW_SIGNATURE, cache=True)
def lqg_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the LQG controller for every lane: correct, feedback, clip, predict (module doc)."""
    n = U.size
    dim = int(C[DIM])
    Fv = X[_F0 : _F0 + dim]
    G = X[_KG0 : _KG0 + len(ROWS)]
    correct(M, X, C, n, dim, _MAT0 + dim * dim, _MAT0 + dim * dim + dim)
    _shapes(X, C, n, X[_SH])
    clock(M, G, C, n, X[_REF])
    base_torques(X, C, n, X[_SH : _SH + 1], X[_REF], X[_TQ : _TQ + 2])
    feedback(X, G, C, n, U, X[_TQ : _TQ + 2], X[_REF])
    clip(U, n, C[U_MAX])
    model_rhs(X, C, n, dim, U, X[_SH : _SH + 1], Fv, Fv, False)
    # the increments of every estimate at once (Fv holds f at the corrected estimates)
    predict_mean(X, C, n, dim, _MAT0, Fv, X[_W : _W + dim])


def law_rows(c, G: np.ndarray) -> None:
    """The law's rows G (:data:`ROWS`, n) from the reset :class:`controllers.observer.LQGController` c."""
    G[KG : KG + 3] = np.broadcast_to(c.K, (c.n, 3)).T
    G[THETA0] = np.broadcast_to(c._theta0, (c.n,))
    G[TIME] = c._t
    G[TARGET] = c.omega_ref


def lqg_constants(c, dim: int) -> np.ndarray:
    """The values of :data:`controllers.compiled.observer_law.CONSTANTS` and :data:`EXTRA` of the reset
    :class:`controllers.observer.LQGController` c."""
    mdl, p = c.model, c.params
    values = dict.fromkeys(CONSTANTS, 0.0) | dict(
        dt=c.dt, eps=mdl.dynamics.eps, h=1e-5, Ju=p.Ju, Jl=p.Jl, km=p.km, kth=p.ktheta, Tcu=p.Tcu, dTcu=p.dTcu,
        bu=p.bu, dbu=p.dbu, Ts=p.Ts, Tc=p.Tc, ws=p.ws, delta=p.delta, bb=p.bb, u_max=c.u_max,
        scale=float(mdl.dynamics.scale), has_du=float(mdl.has_du), dim=float(dim),
    )  # fmt: skip
    extra = dict(
        outer_gain=c.outer_gain, outer_start=c.outer_start, upper_coulomb=mdl.upper_coulomb,
        upper_damping=mdl.upper_damping, slip_eps=1e-3, dt_lqg=c.dt,
    )  # fmt: skip
    return np.array([float(values[k]) for k in CONSTANTS] + [float(extra[k]) for k in EXTRA])


def lqg_law(c):
    """The compiled law of an :class:`controllers.observer.LQGController` after its reset, or None.

    None when its settings need what this compiled law does not run: a model with effects
    (:mod:`controllers.compiled.model_law` runs those), the ``descent`` fallback for some targets.

    Parameters
    ----------
    c : LQGController
        The controller, reset.

    Returns
    -------
    controllers.compiled.CompiledLaw or None
        The law with its state (the estimates, the gains, the integral's start angle, the clock and the target) and
        constants (:data:`controllers.compiled.observer_law.CONSTANTS`, :data:`EXTRA`, Gamma, Kf, H).
    """
    from . import CompiledLaw

    mdl = c.model
    dim = mdl.Ad.shape[0]
    if not (plain_model(c) and filter_settled(c, dim, MAX_DIM) and dim == mdl.nc and not np.any(mdl.gamma_old)):
        return None
    X = np.zeros((N_ROWS, c.n))
    X[:dim] = c._x
    law_rows(c, X[_KG0 : _KG0 + len(ROWS)])
    C = np.concatenate([lqg_constants(c, dim)] + [np.ravel(a) for a in (mdl.gamma_new, c.Kf, mdl.H)])
    return CompiledLaw(lqg_step, np.ascontiguousarray(X), np.ascontiguousarray(C, dtype=np.float64))
