"""The ``lqg-2enc`` controller's law compiled: gain-scheduled LQG on the motor and lower encoders.

What :meth:`controllers.two_encoder.TwoEncoderLQG.act` computes each period, for every lane, on a model without
effects: the design nearest the lane's reference speed (a grid of :data:`controllers.two_encoder.GRID` rad/s), the
equilibrium there (winding and voltage interpolated on the grid, shifted by the estimated lower-disc torque), the
filter's correction with both encoders' angles (the innovations' dead band), the LQR voltage, the clip, the
prediction with the design's matrices, then the reference angle, the reference speed's lag towards the target
(the approach from above, its hold and ramp) and the clock.

State rows (per lane): the absolute estimates (nx), the time since reset (s), the reference speed (rad/s), the
reference angle (rad) and the target (rad/s).  Constants: :data:`SCALARS`, then the grid (G speeds, rad/s), the
equilibrium's windings (rad) and voltages (V) on it, then per design A (nx x nx), B (nx), C (2 x nx), K (nx) and
L (nx x 2), row-major.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE, M_TL, M_TU

__all__ = ["two_encoder_step", "two_encoder_law", "SCALARS", "MAX_NX"]

MAX_NX = 16
SCALARS = ("dt", "grid_step", "n_grid", "nx", "approach", "hold", "ramp", "tau_ref", "feedforward", "ktheta",
           "u_max", "dead_band", "count")  # fmt: skip
DT, GSTEP, NG, NX, APPROACH, HOLD, RAMP, TAU_REF, FF, KTH, U_MAX, DEAD_BAND, COUNT = range(len(SCALARS))
_G0 = len(SCALARS)
TIME, REF, THETA_REF, TARGET = MAX_NX, MAX_NX + 1, MAX_NX + 2, MAX_NX + 3
N_ROWS = MAX_NX + 4


@njit(inline="always")
def _interp(x, C, g0, f0, ng):
    """numpy.interp(x, grid, values) on the grid at C[g0:] and the values at C[f0:] (ng points)."""
    if x <= C[g0]:
        return C[f0]
    if x >= C[g0 + ng - 1]:
        return C[f0 + ng - 1]
    lo, hi = 0, ng - 1
    while hi - lo > 1:  # C[g0 + lo] <= x < C[g0 + hi]
        mid = (lo + hi) // 2
        if C[g0 + mid] <= x:
            lo = mid
        else:
            hi = mid
    slope = (C[f0 + lo + 1] - C[f0 + lo]) / (C[g0 + lo + 1] - C[g0 + lo])
    return slope * (x - C[g0 + lo]) + C[f0 + lo]


@njit(LAW_SIGNATURE, cache=True, error_model="numpy")
def two_encoder_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the two-encoder LQG for every lane (module doc)."""
    n = U.size
    dt, gstep, ng, nx = C[DT], C[GSTEP], int(C[NG]), int(C[NX])
    kt, u_max, ff = C[KTH], C[U_MAX], C[FF]
    a0 = _G0 + ng  # windings on the grid, then voltages, then the designs
    u0 = a0 + ng
    size = nx * nx + nx + 2 * nx + nx + 2 * nx
    q = 2.0 * np.pi / C[COUNT]
    band = C[DEAD_BAND] > 0
    w = C[DEAD_BAND] * q / 2
    eq = np.empty(nx)
    xd = np.empty(nx)
    xn = np.empty(nx)
    for k in range(n):
        r = max(X[REF, k], gstep)
        j = min(max(int(np.rint(r / gstep)) - 1, 0), ng - 1)
        base = u0 + ng + j * size
        A, B, Cm, K, L = base, base + nx * nx, base + nx * nx + nx, base + nx * nx + 3 * nx, base + nx * nx + 4 * nx
        a_eq = _interp(r, C, _G0, a0, ng)
        u_eq = _interp(r, C, _G0, u0, ng)
        shift = ff * X[5, k] / kt
        a_eq = a_eq - shift
        eq[0], eq[1], eq[2], eq[3], eq[4], eq[5] = X[THETA_REF, k] + shift, r, a_eq, r, u_eq, 0.0
        for i in range(6, nx):
            eq[i] = u_eq
        for i in range(nx):
            xd[i] = X[i, k] - eq[i]
        y0 = M[M_TU, k] - eq[0]
        y1 = M[M_TL, k] - eq[0] - a_eq
        c0 = 0.0
        c1 = 0.0
        for i in range(nx):
            c0 += C[Cm + i] * xd[i]
            c1 += C[Cm + nx + i] * xd[i]
        i0, i1 = y0 - c0, y1 - c1
        if band:  # within the encoder's quantisation cell the reading says nothing more
            i0, i1 = i0 + q / 2, i1 + q / 2
            i0 = i0 - min(max(i0, -w), w)
            i1 = i1 - min(max(i1, -w), w)
        for i in range(nx):
            xd[i] = xd[i] + (C[L + 2 * i] * i0 + C[L + 2 * i + 1] * i1)
        kx = 0.0
        for i in range(nx):
            kx += C[K + i] * xd[i]
        u = min(max(u_eq - kx, -u_max), u_max)
        U[k] = u
        for i in range(nx):
            s = 0.0
            for m in range(nx):
                s += C[A + i * nx + m] * xd[m]
            xn[i] = s + C[B + i] * (u - u_eq)
        theta_ref = X[THETA_REF, k] + r * dt
        X[THETA_REF, k] = theta_ref
        for i in range(nx):
            X[i, k] = xn[i] + eq[i]
        X[0, k] = xn[0] + theta_ref + shift
        tk = X[TIME, k]
        ramp = C[RAMP]
        if ramp > 0:
            s = min(max((tk - C[HOLD]) / ramp, 0.0), 1.0)
        else:
            s = 1.0 if tk >= C[HOLD] else 0.0
        wt = X[TARGET, k]
        target = C[APPROACH] + s * (wt - C[APPROACH]) if wt < C[APPROACH] else wt
        X[REF, k] = X[REF, k] + dt / C[TAU_REF] * (target - X[REF, k])
        X[TIME, k] = tk + dt


def two_encoder_law(c):
    """The compiled law of a :class:`controllers.two_encoder.TwoEncoderLQG` after its reset, or None.

    None for a model with effects (the composition's equilibrium, readings and input map per period keep the
    step-by-step path).

    Parameters
    ----------
    c : TwoEncoderLQG
        The controller, reset.

    Returns
    -------
    controllers.compiled.CompiledLaw or None
        The law with its state (the estimates, the clock, the reference speed and angle, the target) and constants
        (:data:`SCALARS`, the grid, the equilibrium on it and the designs).
    """
    from . import CompiledLaw

    nx = c._A.shape[1]  # the grid starts at its step (controllers.two_encoder.GRID)
    if c.dyn is not None or c.compensates or nx > MAX_NX or nx < 6:
        return None
    n = c.n
    X = np.zeros((N_ROWS, n))
    X[:nx] = c.x.T
    X[TIME], X[REF], X[THETA_REF], X[TARGET] = c.t, c.r, c.theta_ref, c.omega_ref
    d = c.design
    values = dict(
        dt=c.dt, grid_step=float(c._grid[0]), n_grid=float(c._grid.size), nx=float(nx), approach=c.approach,
        hold=c.hold, ramp=c.ramp, tau_ref=c.tau_ref, feedforward=c.feedforward, ktheta=c.params.ktheta, u_max=c.u_max,
        dead_band=d.dead_band, count=float(d.counts),
    )  # fmt: skip
    designs = np.concatenate(
        [np.ravel(a) for j in range(c._grid.size) for a in (c._A[j], c._B[j][:, 0], c._C[j], c._K[j][0], c._L[j])]
    )
    C = np.concatenate([[float(values[k]) for k in SCALARS], c._grid, c._alpha_grid, c._u_grid, designs])
    return CompiledLaw(two_encoder_step, np.ascontiguousarray(X), np.ascontiguousarray(C, dtype=np.float64))
