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
    model_rhs,
)

__all__ = ["lqg_step", "lqg_law", "EXTRA"]

EXTRA = ("outer_gain", "outer_start", "upper_coulomb", "upper_damping", "slip_eps", "dt_lqg")
"""Constants after the observer's: integral gain (1/s), its start (s), Tcu + dTcu (N m), bu + dbu (N m s/rad), the
speed below which the lower disc is taken at rest for the friction estimate (rad/s), the period (s)."""
OUTER_GAIN, OUTER_START, UCOUL, UDAMP, SLIP_EPS, DT_LQG = range(len(CONSTANTS), len(CONSTANTS) + len(EXTRA))
_MAT0 = len(CONSTANTS) + len(EXTRA)  # then Gamma (dim x dim), Kf (dim), H (dim)

_KG0 = MAX_DIM  # LQR gains on (alpha, omega_u, omega_l)
THETA0, TIME, TARGET = _KG0 + 3, _KG0 + 4, _KG0 + 5
_F0 = TARGET + 1  # work: the right-hand side (MAX_DIM rows), the shape at |omega_l|
_SH = _F0 + MAX_DIM
N_ROWS = _SH + 3


@njit(cache=True, error_model="numpy")
def _correct(M, X, C, n, dim):
    """x += Kf (theta_u - H x): the stationary filter's correction with the measured motor angles."""
    kf, hh = _MAT0 + dim * dim, _MAT0 + dim * dim + dim
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
def _feedback(M, X, C, n, U, SH):
    """The LQR voltage about the equilibrium the friction estimate defines (V, clipped) into U."""
    kt, km, u_max = C[KTH], C[KM], C[U_MAX]
    Ts, Tc, bb, ws, delta = C[TS], C[TC], C[BB], C[WS], C[DELTA]
    eps, g, t0 = C[SLIP_EPS], C[OUTER_GAIN], C[OUTER_START]
    scale = C[SCALE] > 0
    shape_eps = _shape(eps, ws, delta)
    for k in range(n):
        al, wu, wl, d = X[2, k], X[1, k], X[3, k], X[4, k]
        slip = abs(wl) > eps
        w = wl if slip else eps
        aw = abs(w)
        e = SH[0, k] if slip else shape_eps
        T = (1.0 if w > 0 else (-1.0 if w < 0 else 0.0)) * (Tc + (Ts - Tc) * e + bb * aw)
        T = T * (1.0 + d) if scale else T + d
        d_hat = T if slip else -kt * al
        alpha_star = -d_hat / kt
        t = X[TIME, k] + C[DT_LQG]
        X[TIME, k] = t
        ref = X[TARGET, k]
        if g > 0:  # integral action on the measured motor angle
            th = M[M_TU, k]
            if t <= t0:
                X[THETA0, k] = th
            z = th - X[THETA0, k] - ref * max(t - t0, 0.0)
            ref = min(max(ref - g * z, 0.5 * ref), 1.5 * ref)
        u_star = (C[UCOUL] + C[UDAMP] * ref + d_hat) / km
        fb = X[_KG0, k] * (al - alpha_star) + X[_KG0 + 1, k] * (wu - ref) + X[_KG0 + 2, k] * (wl - ref)
        U[k] = min(max(u_star - fb, -u_max), u_max)


@njit(cache=True, error_model="numpy")
def _predict(X, C, n, dim, Fv):
    """x += Gamma f(x, u) (the exponential Euler mean)."""
    for i in range(dim):
        for m in range(dim):
            g = C[_MAT0 + i * dim + m]
            if g != 0.0:
                for k in range(n):
                    X[i, k] += g * Fv[m, k]


@njit(LAW_SIGNATURE, cache=True)
def lqg_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the LQG controller for every lane: correct, feedback, clip, predict (module doc)."""
    n = U.size
    dim = int(C[DIM])
    Fv = X[_F0 : _F0 + dim]
    SH = X[_SH : _SH + 3]
    _correct(M, X, C, n, dim)
    _shapes(X, C, n, SH[0])
    _feedback(M, X, C, n, U, SH)
    model_rhs(X, C, n, dim, U, SH, Fv, Fv, False)
    # the increments of every estimate at once (Fv holds f at the corrected estimates)
    _predict(X, C, n, dim, Fv)


def lqg_law(c):
    """The compiled law of an :class:`controllers.observer.LQGController` after its reset, or None.

    None when its settings need what the compiled law does not run: a model with effects, a delay or a
    lag, the ``descent`` fallback for some targets.

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

    mdl, p = c.model, c.params
    dim = mdl.Ad.shape[0]
    plain = (
        not c.effects.composition.effects
        and c._descent is None
        and mdl.line_index < 0
        and mdl.lag_index < 0
        and not (mdl.reads_effects or mdl.compensates)
        and mdl.friction_known
        and dim == mdl.nc <= MAX_DIM
        and not np.any(mdl.gamma_old)
        and np.array_equal(mdl.dynamics.vector, p.to_vector())
    )
    if not plain:
        return None
    n = c.n
    X = np.zeros((N_ROWS, n))
    X[:dim] = c._x
    X[_KG0 : _KG0 + 3] = np.broadcast_to(c.K, (n, 3)).T
    X[THETA0] = np.broadcast_to(c._theta0, (n,))
    X[TIME] = c._t
    X[TARGET] = c.omega_ref
    values = dict.fromkeys(CONSTANTS, 0.0) | dict(
        dt=c.dt, eps=mdl.dynamics.eps, h=1e-5, Ju=p.Ju, Jl=p.Jl, km=p.km, kth=p.ktheta, Tcu=p.Tcu, dTcu=p.dTcu,
        bu=p.bu, dbu=p.dbu, Ts=p.Ts, Tc=p.Tc, ws=p.ws, delta=p.delta, bb=p.bb, u_max=c.u_max,
        scale=float(mdl.dynamics.scale), has_du=float(mdl.has_du), dim=float(dim),
    )  # fmt: skip
    extra = dict(
        outer_gain=c.outer_gain, outer_start=c.outer_start, upper_coulomb=mdl.upper_coulomb,
        upper_damping=mdl.upper_damping, slip_eps=1e-3, dt_lqg=c.dt,
    )  # fmt: skip
    C = np.concatenate(
        [[float(values[k]) for k in CONSTANTS], [float(extra[k]) for k in EXTRA]]
        + [np.ravel(a) for a in (mdl.gamma_new, c.Kf, mdl.H)]
    )
    return CompiledLaw(lqg_step, np.ascontiguousarray(X), np.ascontiguousarray(C, dtype=np.float64))
