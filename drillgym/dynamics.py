"""Equations of motion of the rig (docs/model.md), compiled with numba.

Generalised coordinates used by the kernels are q' = (theta_u, theta_l, x, y):
the report's q = (x, y, alpha, theta_u) with alpha = theta_l - theta_u, so that
the two friction torques act on single coordinates (a stuck disc is one
coordinate with zero velocity).  The transformation q = T q' turns the model's
Lagrange equations M q'' + h = Q into M' q''' + h' = Q' with M' = T^T M T:

    M' = | Ju + m r^2   G    -m y   m x |      P = e mr, c = cos alpha, s = sin alpha
         | G            Jl   -P s   P c |      G = P (x c + y s),  r^2 = x^2 + y^2
         | -m y        -P s   m     0   |
         | m x          P c   0     m   |

    h'_u = -P (x s - y c) wl^2 + 2 m W (x vx + y vy) - k_theta alpha
    h'_l =  2 P W (c vx + s vy) + P W^2 (x s - y c) + k_theta alpha
    h'_x = -m x W^2 - 2 m W vy - P c wl^2
    h'_y = -m y W^2 + 2 m W vx - P s wl^2

plus the model's lateral spring/damper forces (``isotropic_lateral_forces``).
Generalised forces: Q'_u = km u - Tfu(wu), Q'_l = -Tfl(wl), plus whatever the
composition's effects add (:mod:`drillgym.effects`).

With x = y = 0 held (torsional, free_vibration) M' = diag(Ju, Jl): the report's
reduced equations (3.19), (3.20).

A stuck disc contributes an unknown friction torque lambda that keeps its
acceleration zero (the Lagrange-multiplier form of the switch model).  The
lateral accelerations are eliminated first (Schur complement of the m I block),
which leaves a 2x2 system in the two disc accelerations where the constraints
and multipliers are explicit.  The right-hand side that assembles these pieces,
``state_derivative``, is a kernel template compiled per composition of effects
(:mod:`drillgym.kernels.model`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .configurations import Configuration
from .params import IDX
from .vmath import FASTMATH

UPPER = int(Configuration.UPPER)
TORSIONAL = int(Configuration.TORSIONAL)
LATERAL = int(Configuration.LATERAL)
COUPLED = int(Configuration.COUPLED)
FREE_VIBRATION = int(Configuration.FREE_VIBRATION)

_Ju, _km, _Jl, _kth = IDX.Ju, IDX.km, IDX.Jl, IDX.ktheta
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e

# indices of the mechanical state vector (see configurations.py); effect states follow from index 8
S_TU, S_TL, S_WU, S_WL, S_X, S_Y, S_VX, S_VY = 0, 1, 2, 3, 4, 5, 6, 7


@njit(cache=True, _nrt=False)
def brake_on(cfg: int) -> bool:
    return cfg == TORSIONAL or cfg == COUPLED


@njit(cache=True, _nrt=False)
def lateral_free(cfg: int) -> bool:
    return cfg == LATERAL or cfg == COUPLED


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


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def reduced_accelerations(
    drive: float,
    string: float,
    extra_l: float,
    tfu: float,
    tfl: float,
    Ju: float,
    Jl: float,
    slip_u: bool,
    slip_l: bool,
) -> tuple:
    """The reduced equations (3.19), (3.20): Ju wu' = drive + string - Tfu, Jl wl' = -string + extra_l - Tfl.

    drive = km u (+ any extra torque on the upper disc) (N m), string = ktheta alpha (+ extra string
    torques) (N m, on the upper disc), extra_l an extra torque on the lower disc (N m), tfu/tfl the
    slip torques.  A stuck disc has zero acceleration and its holding torque as friction.
    Returns (wu', wl', Tfu, Tfl).
    """
    Fu = drive + string
    Fl = extra_l - string
    a_u = (Fu - tfu) / Ju if slip_u else 0.0
    a_l = (Fl - tfl) / Jl if slip_l else 0.0
    return a_u, a_l, (tfu if slip_u else Fu), (tfl if slip_l else Fl)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def isotropic_lateral_forces(x: float, yy: float, vx: float, vy: float, W: float, k: float, b: float) -> tuple:
    """The model's spring and damper terms as generalised forces (Q_u, Q_x, Q_y) for kx = ky, bx = by."""
    return (b * (yy * vx - x * vy - W * (x * x + yy * yy)), -k * x - b * (vx - yy * W), -k * yy - b * (vy + x * W))


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def coupled_system(
    x: float,
    yy: float,
    vx: float,
    vy: float,
    W: float,
    wl: float,
    s: float,
    c: float,
    m: float,
    P: float,
    Ju: float,
    Jl: float,
    drive: float,
    string: float,
    extra_l: float,
    tfu: float,
    tfl: float,
    Qu: float,
    Qx: float,
    Qy: float,
    slip_u: bool,
    slip_l: bool,
) -> tuple:
    """The coupled equations of docs/model.md with the lateral accelerations eliminated (Schur complement of the
    m I block): the 2x2 system S (wu', wl') = g of the discs, and the lateral right-hand sides.
    Arguments as :func:`full_accelerations`.  Returns (s00, s01, s11, g0, g1, F2, F3): S's entries
    (kg m^2), g (N m), F2, F3 (N)."""
    xs_yc = x * s - yy * c
    r2 = x * x + yy * yy
    F0 = drive - (tfu if slip_u else 0.0) + Qu + P * xs_yc * wl * wl - 2.0 * m * W * (x * vx + yy * vy) + string
    F1 = extra_l - (tfl if slip_l else 0.0) - 2.0 * P * W * (c * vx + s * vy) - P * W * W * xs_yc - string
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
    return s00, s01, s11, g0, g1, F2, F3


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def lateral_accelerations(
    x: float, yy: float, s: float, c: float, m: float, P: float, F2: float, F3: float, a0: float, a1: float
) -> tuple:
    """(vx', vy') (m/s^2) from the lateral right-hand sides F2, F3 (N) and the disc accelerations
    a0 = wu', a1 = wl' (rad/s^2): the lateral rows of the model's mass matrix."""
    inv_m = 1.0 / m
    return (F2 + m * yy * a0 + P * s * a1) * inv_m, (F3 - m * x * a0 - P * c * a1) * inv_m


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def full_accelerations(
    x: float,
    yy: float,
    vx: float,
    vy: float,
    W: float,
    wl: float,
    s: float,
    c: float,
    m: float,
    P: float,
    Ju: float,
    Jl: float,
    drive: float,
    string: float,
    extra_l: float,
    tfu: float,
    tfl: float,
    Qu: float,
    Qx: float,
    Qy: float,
    slip_u: bool,
    slip_l: bool,
) -> tuple:
    """Accelerations of the four coordinates (docs/model.md), with stuck discs as constraints.

    s, c = sin, cos of alpha; m = mr + mt, P = e mr; drive = km u (+ extra upper torque); string on the
    upper disc; extra_l an extra torque on the lower disc;
    tfu/tfl slip torques (ignored for a stuck disc); Q* lateral generalised forces.
    The lateral accelerations are eliminated (Schur complement of the m I block, :func:`coupled_system`),
    leaving a 2x2 system in (wu', wl') where a stuck disc's constraint and multiplier are explicit.
    Returns (wu', wl', vx', vy', Tfu, Tfl).
    """
    s00, s01, s11, g0, g1, F2, F3 = coupled_system(
        x, yy, vx, vy, W, wl, s, c, m, P, Ju, Jl, drive, string, extra_l, tfu, tfl, Qu, Qx, Qy, slip_u, slip_l
    )
    det = s00 * s11 - s01 * s01
    a0 = ((s11 * g0 - s01 * g1) / det if slip_l else g0 / s00) if slip_u else 0.0
    a1 = ((s00 * g1 - s01 * g0) / det if slip_u else g1 / s11) if slip_l else 0.0
    fu = tfu if slip_u else g0 - s01 * a1
    fl = tfl if slip_l else g1 - s01 * a0
    ax, ay = lateral_accelerations(x, yy, s, c, m, P, F2, F3, a0, a1)
    return a0, a1, ax, ay, fu, fl
