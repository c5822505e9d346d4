"""Equations of motion of the rig (MODEL.md), compiled with numba.

Generalised coordinates used by the kernels are q' = (theta_u, theta_l, x, y):
the report's q = (x, y, alpha, theta_u) with alpha = theta_l - theta_u, so that
the two friction torques act on single coordinates (a stuck disc is one
coordinate with zero velocity).  The transformation q = T q' turns MODEL.md's
Lagrange equations M q'' + h = Q into M' q''' + h' = Q' with M' = T^T M T:

    M' = | Ju + m r^2   G    -m y   m x |      P = e mr, c = cos alpha, s = sin alpha
         | G            Jl   -P s   P c |      G = P (x c + y s),  r^2 = x^2 + y^2
         | -m y        -P s   m     0   |
         | m x          P c   0     m   |

    h'_u = -P (x s - y c) wl^2 + 2 m W (x vx + y vy) - k_theta alpha
    h'_l =  2 P W (c vx + s vy) + P W^2 (x s - y c) + k_theta alpha
    h'_x = -m x W^2 - 2 m W vy - P c wl^2
    h'_y = -m y W^2 + 2 m W vx - P s wl^2

plus the lateral spring/damper forces, written in the fixed frame
(X = x cos theta_u - y sin theta_u, Y = x sin theta_u + y cos theta_u) so that
anisotropy (kx != ky) and lateral dry friction are the same formula; for kx =
ky = k, bx = by = b they are exactly MODEL.md's k and b terms (tested).
Generalised forces: Q'_u = km u - Tfu(wu), Q'_l = -Tfl(wl).

With x = y = 0 held (torsional, free_vibration) M' = diag(Ju, Jl): the report's
reduced equations (3.19), (3.20).

A stuck disc contributes an unknown friction torque lambda that keeps its
acceleration zero (the Lagrange-multiplier form of the switch model).  The
lateral accelerations are eliminated first (Schur complement of the m I block),
which leaves a 2x2 system in the two disc accelerations where the constraints
and multipliers are explicit.  ``state_derivative`` returns these torques so the integrator can
release a disc when lambda leaves its stick set.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .configurations import Configuration
from .friction import lower_slip_torque, upper_slip_torque
from .params import IDX

UPPER = int(Configuration.UPPER)
TORSIONAL = int(Configuration.TORSIONAL)
LATERAL = int(Configuration.LATERAL)
COUPLED = int(Configuration.COUPLED)
FREE_VIBRATION = int(Configuration.FREE_VIBRATION)

_Ju, _km, _Jl, _kth = IDX.Ju, IDX.km, IDX.Jl, IDX.ktheta
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e
_dtheta, _tau_m, _dk, _db, _Fc_lat = IDX.dtheta, IDX.tau_m, IDX.dk, IDX.db, IDX.Fc_lat

LATERAL_COULOMB_EPS = 1e-4  # m/s: regularisation speed of the lateral dry-friction direction

# indices of the state vector (see configurations.py)
S_TU, S_TL, S_WU, S_WL, S_X, S_Y, S_VX, S_VY, S_UM = 0, 1, 2, 3, 4, 5, 6, 7, 8


@njit(cache=True, _nrt=False)
def brake_on(cfg: int) -> bool:
    return cfg == TORSIONAL or cfg == COUPLED


@njit(cache=True, _nrt=False)
def lateral_free(cfg: int) -> bool:
    return cfg == LATERAL or cfg == COUPLED


@njit(cache=True, fastmath=True, _nrt=False)
def lateral_generalised_forces(y: np.ndarray, p: np.ndarray) -> tuple:
    """Spring, damper and dry-friction forces of the lateral constraints (fixed frame),
    as generalised forces on (theta_u, x, y): returns (Q_u, Q_x, Q_y) in N m, N, N."""
    th = y[S_TU]
    W = y[S_WU]
    x = y[S_X]
    yy = y[S_Y]
    ct = math.cos(th)
    st = math.sin(th)
    X = x * ct - yy * st
    Y = x * st + yy * ct
    Xd = ct * y[S_VX] - st * y[S_VY] - Y * W
    Yd = st * y[S_VX] + ct * y[S_VY] + X * W
    kx = p[_k] + p[_dk]
    ky = p[_k] - p[_dk]
    bx = p[_b] + p[_db]
    by = p[_b] - p[_db]
    FX = -kx * X - bx * Xd
    FY = -ky * Y - by * Yd
    if p[_Fc_lat] > 0.0:
        vn = math.sqrt(Xd * Xd + Yd * Yd + LATERAL_COULOMB_EPS * LATERAL_COULOMB_EPS)
        FX -= p[_Fc_lat] * Xd / vn
        FY -= p[_Fc_lat] * Yd / vn
    Qx = FX * ct + FY * st
    Qy = -FX * st + FY * ct
    Qu = -FX * Y + FY * X
    return Qu, Qx, Qy


@njit(cache=True, _nrt=False)
def mass_matrix(y: np.ndarray, p: np.ndarray, M: np.ndarray) -> None:
    """Fill M (4x4) with M'(q) in the order (theta_u, theta_l, x, y)."""
    m = p[_mr] + p[_mt]
    P = p[_e] * p[_mr]
    a = y[S_TL] - y[S_TU]
    c = math.cos(a)
    s = math.sin(a)
    x = y[S_X]
    yy = y[S_Y]
    G = P * (x * c + yy * s)
    M[0, 0] = p[_Ju] + m * (x * x + yy * yy)
    M[0, 1] = G
    M[0, 2] = -m * yy
    M[0, 3] = m * x
    M[1, 1] = p[_Jl]
    M[1, 2] = -P * s
    M[1, 3] = P * c
    M[2, 2] = m
    M[2, 3] = 0.0
    M[3, 3] = m
    for i in range(4):
        for j in range(i):
            M[i, j] = M[j, i]


@njit(inline="always", fastmath=True, error_model="numpy")
def reduced_accelerations(drive: float, string: float, tfu: float, tfl: float, Ju: float, Jl: float,
                          slip_u: bool, slip_l: bool) -> tuple:
    """The reduced equations (3.19), (3.20): Ju wu' = drive + string - Tfu, Jl wl' = -string - Tfl.

    drive = km u (N m), string = ktheta alpha + dtheta alpha' (N m, on the upper disc), tfu/tfl the
    slip torques.  A stuck disc has zero acceleration and its holding torque as friction.
    Returns (wu', wl', Tfu, Tfl).
    """
    Fu = drive + string
    Fl = -string
    a_u = (Fu - tfu) / Ju if slip_u else 0.0
    a_l = (Fl - tfl) / Jl if slip_l else 0.0
    return a_u, a_l, (tfu if slip_u else Fu), (tfl if slip_l else Fl)


@njit(inline="always", fastmath=True, error_model="numpy")
def isotropic_lateral_forces(x: float, yy: float, vx: float, vy: float, W: float, k: float, b: float) -> tuple:
    """MODEL.md's spring and damper terms as generalised forces (Q_u, Q_x, Q_y) for kx = ky, bx = by."""
    return (b * (yy * vx - x * vy - W * (x * x + yy * yy)), -k * x - b * (vx - yy * W), -k * yy - b * (vy + x * W))


@njit(inline="always", fastmath=True, error_model="numpy")
def full_accelerations(x: float, yy: float, vx: float, vy: float, W: float, wl: float, s: float, c: float,
                       m: float, P: float, Ju: float, Jl: float, drive: float, string: float, tfu: float,
                       tfl: float, Qu: float, Qx: float, Qy: float, slip_u: bool, slip_l: bool) -> tuple:
    """Accelerations of the four coordinates (MODEL.md), with stuck discs as constraints.

    s, c = sin, cos of alpha; m = mr + mt, P = e mr; drive = km u; string on the upper disc;
    tfu/tfl slip torques (ignored for a stuck disc); Q* lateral generalised forces.
    The lateral accelerations are eliminated (Schur complement of the m I block), leaving a
    2x2 system in (wu', wl') where a stuck disc's constraint and multiplier are explicit.
    Returns (wu', wl', vx', vy', Tfu, Tfl).
    """
    xs_yc = x * s - yy * c
    r2 = x * x + yy * yy
    F0 = drive - (tfu if slip_u else 0.0) + Qu + P * xs_yc * wl * wl - 2.0 * m * W * (x * vx + yy * vy) + string
    F1 = -(tfl if slip_l else 0.0) - 2.0 * P * W * (c * vx + s * vy) - P * W * W * xs_yc - string
    F2 = Qx + m * x * W * W + 2.0 * m * W * vy + P * c * wl * wl
    F3 = Qy + m * yy * W * W - 2.0 * m * W * vx + P * s * wl * wl
    c00 = -m * yy
    c01 = m * x
    c10 = -P * s
    c11 = P * c
    inv_m = 1.0 / m
    s00 = Ju + m * r2 - (c00 * c00 + c01 * c01) * inv_m
    s01 = P * (x * c + yy * s) - (c00 * c10 + c01 * c11) * inv_m
    s11 = Jl - (c10 * c10 + c11 * c11) * inv_m
    g0 = F0 - (c00 * F2 + c01 * F3) * inv_m
    g1 = F1 - (c10 * F2 + c11 * F3) * inv_m
    det = s00 * s11 - s01 * s01
    a0 = ((s11 * g0 - s01 * g1) / det if slip_l else g0 / s00) if slip_u else 0.0
    a1 = ((s00 * g1 - s01 * g0) / det if slip_u else g1 / s11) if slip_l else 0.0
    fu = tfu if slip_u else g0 - s01 * a1
    fl = tfl if slip_l else g1 - s01 * a0
    return a0, a1, (F2 - c00 * a0 - c10 * a1) * inv_m, (F3 - c01 * a0 - c11 * a1) * inv_m, fu, fl


@njit(cache=True, fastmath=True, _nrt=False)
def state_derivative(t: float, y: np.ndarray, mode: np.ndarray, u: float, p: np.ndarray, cfg: int,
                     smooth_eps: float, dy: np.ndarray, fric: np.ndarray) -> None:
    """dy/dt of the state for constant input u (V) and friction modes ``mode``.

    Writes the friction torques (Tfu, Tfl) in N m into ``fric`` (for a stuck
    disc: the constraint torque lambda).  ``smooth_eps`` > 0 selects the explicit
    smoothed friction option (sign -> tanh(w/eps), modes ignored).
    """
    for i in range(dy.shape[0]):
        dy[i] = 0.0
    wu = y[S_WU]
    wl = y[S_WL]
    brake = brake_on(cfg)
    # motor (optionally lagged)
    if p[_tau_m] > 0.0:
        dy[S_UM] = (u - y[S_UM]) / p[_tau_m]
        torque = p[_km] * y[S_UM]
    else:
        torque = p[_km] * u
    dy[S_TU] = wu
    dy[S_TL] = wl
    mu = mode[0]
    ml = mode[1]
    if smooth_eps > 0.0:
        su = math.tanh(wu / smooth_eps)
        sl = math.tanh(wl / smooth_eps)
        tfu = su * upper_slip_torque(wu, 1, p) if su >= 0 else -su * upper_slip_torque(wu, -1, p)
        tfl = sl * lower_slip_torque(wl, 1, y[S_TL], t, p, brake) if sl >= 0 else \
            -sl * lower_slip_torque(wl, -1, y[S_TL], t, p, brake)
        mu = 2  # "slipping, torque given"
        ml = 2
    else:
        tfu = upper_slip_torque(wu, mu, p) if mu != 0 else 0.0
        tfl = lower_slip_torque(wl, ml, y[S_TL], t, p, brake) if ml != 0 else 0.0
    if cfg == FREE_VIBRATION:
        mu = 0  # upper disc clamped: always stuck, unbounded stick set
        dy[S_TU] = 0.0

    if cfg == UPPER:
        if mu == 0:
            fric[0] = torque
            dy[S_WU] = 0.0
        else:
            fric[0] = tfu
            dy[S_WU] = (torque - tfu) / p[_Ju]
        fric[1] = 0.0
        return

    alpha = y[S_TL] - y[S_TU]
    string = p[_kth] * alpha + p[_dtheta] * (wl - wu)  # torque of the string on the upper disc (N m)

    if not lateral_free(cfg):
        a_u, a_l, fu, fl = reduced_accelerations(torque, string, tfu, tfl, p[_Ju], p[_Jl], mu != 0, ml != 0)
        dy[S_WU] = a_u
        dy[S_WL] = a_l
        fric[0] = fu
        fric[1] = fl
        return

    # full four-coordinate equations
    x = y[S_X]
    yy = y[S_Y]
    vx = y[S_VX]
    vy = y[S_VY]
    if p[_dk] == 0.0 and p[_db] == 0.0 and p[_Fc_lat] == 0.0:
        Qu, Qx, Qy = isotropic_lateral_forces(x, yy, vx, vy, wu, p[_k], p[_b])
    else:
        Qu, Qx, Qy = lateral_generalised_forces(y, p)
    s = math.sin(alpha)
    c = math.cos(alpha)
    a_u, a_l, a_x, a_y, fu, fl = full_accelerations(x, yy, vx, vy, wu, wl, s, c, p[_mr] + p[_mt], p[_e] * p[_mr],
                                                    p[_Ju], p[_Jl], torque, string, tfu, tfl, Qu, Qx, Qy,
                                                    mu != 0, ml != 0)
    dy[S_WU] = a_u
    dy[S_WL] = a_l
    dy[S_X] = vx
    dy[S_Y] = vy
    dy[S_VX] = a_x
    dy[S_VY] = a_y
    fric[0] = fu
    fric[1] = fl
