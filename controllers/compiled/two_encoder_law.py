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

from .observer_law import clip

__all__ = ["two_encoder_step", "two_encoder_law", "SCALARS", "MAX_NX"]

MAX_NX = 16
SCALARS = ("dt", "grid_step", "n_grid", "nx", "approach", "hold", "ramp", "tau_ref", "feedforward", "ktheta",
           "u_max", "dead_band", "count")  # fmt: skip
DT, GSTEP, NG, NX, APPROACH, HOLD, RAMP, TAU_REF, FF, KTH, U_MAX, DEAD_BAND, COUNT = range(len(SCALARS))
_G0 = len(SCALARS)
TIME, REF, THETA_REF, TARGET = MAX_NX, MAX_NX + 1, MAX_NX + 2, MAX_NX + 3
# then work rows: the equilibrium's winding and voltage, the deviations, the equilibrium state, the motor's voltage
EQ_ROW = MAX_NX + 4
XD_ROW = EQ_ROW + 2
EV_ROW = XD_ROW + MAX_NX
V_ROW = EV_ROW + MAX_NX
N_ROWS = V_ROW + 1


@njit(inline="always")
def interp(x, C, g0, f0, ng, left):
    """numpy.interp(x, grid, values, left=left) on the increasing grid at C[g0:] and the values at C[f0:] (ng
    points): ``left`` below the grid, the last value beyond it."""
    if x < C[g0]:
        return left
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


@njit(cache=True, error_model="numpy")
def grid_equilibrium(X, C, n, EQ):
    """The equilibrium's winding (rad) and voltage (V) at each lane's reference speed into EQ (2, n), interpolated
    on the designs' grid (the model without effects)."""
    gstep, ng = C[GSTEP], int(C[NG])
    a0 = _G0 + ng
    u0 = a0 + ng
    for k in range(n):
        r = max(X[REF, k], gstep)
        EQ[0, k] = interp(r, C, _G0, a0, ng, C[a0])
        EQ[1, k] = interp(r, C, _G0, u0, ng, C[u0])


@njit(cache=True, error_model="numpy")
def _design(X, C, k):
    """(reference speed (rad/s), first constant of the design nearest it) of lane k."""
    gstep, ng, nx = C[GSTEP], int(C[NG]), int(C[NX])
    r = max(X[REF, k], gstep)
    j = min(max(int(np.rint(r / gstep)) - 1, 0), ng - 1)
    return r, _G0 + 3 * ng + j * (nx * nx + 6 * nx)


@njit(cache=True, error_model="numpy")
def correct(M, X, C, n, U, EQ, XD, EV):
    """The filter's correction with both encoders' angles about the equilibrium EQ (winding (rad) shifted in place
    by the estimated lower torque, voltage (V)): the deviations into XD, the equilibrium state into EV (nx, n), the
    LQR voltage the motor should see (V, not clipped) into U."""
    nx, kt, ff = int(C[NX]), C[KTH], C[FF]
    q = 2.0 * np.pi / C[COUNT]
    band = C[DEAD_BAND] > 0
    w = C[DEAD_BAND] * q / 2
    for k in range(n):
        r, base = _design(X, C, k)
        Cm, K, L = base + nx * nx + nx, base + nx * nx + 3 * nx, base + nx * nx + 4 * nx
        u_eq = EQ[1, k]
        shift = ff * X[5, k] / kt
        a_eq = EQ[0, k] - shift
        EQ[0, k] = a_eq
        EV[0, k], EV[1, k], EV[2, k], EV[3, k], EV[4, k], EV[5, k] = X[THETA_REF, k] + shift, r, a_eq, r, u_eq, 0.0
        for i in range(6, nx):
            EV[i, k] = u_eq
        for i in range(nx):
            XD[i, k] = X[i, k] - EV[i, k]
        y0 = M[M_TU, k] - EV[0, k]
        y1 = M[M_TL, k] - EV[0, k] - a_eq
        c0 = 0.0
        c1 = 0.0
        for i in range(nx):
            c0 += C[Cm + i] * XD[i, k]
            c1 += C[Cm + nx + i] * XD[i, k]
        i0, i1 = y0 - c0, y1 - c1
        if band:  # within the encoder's quantisation cell the reading says nothing more
            i0, i1 = i0 + q / 2, i1 + q / 2
            i0 = i0 - min(max(i0, -w), w)
            i1 = i1 - min(max(i1, -w), w)
        for i in range(nx):
            XD[i, k] = XD[i, k] + (C[L + 2 * i] * i0 + C[L + 2 * i + 1] * i1)
        kx = 0.0
        for i in range(nx):
            kx += C[K + i] * XD[i, k]
        U[k] = u_eq - kx


@njit(cache=True, error_model="numpy")
def predict(X, C, n, V, EQ, XD, EV):
    """The deviations XD one period on with the voltage at the motor V (V), back in absolute coordinates about EV;
    then the reference angle, the reference speed's lag towards the target (its approach) and the clock."""
    dt, nx, kt, ff = C[DT], int(C[NX]), C[KTH], C[FF]
    xn = np.empty(nx)
    for k in range(n):
        r, A = _design(X, C, k)
        B = A + nx * nx
        for i in range(nx):
            s = 0.0
            for m in range(nx):
                s += C[A + i * nx + m] * XD[m, k]
            xn[i] = s + C[B + i] * (V[k] - EQ[1, k])
        shift = ff * X[5, k] / kt
        theta_ref = X[THETA_REF, k] + r * dt
        X[THETA_REF, k] = theta_ref
        for i in range(nx):
            X[i, k] = xn[i] + EV[i, k]
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


@njit(LAW_SIGNATURE, cache=True, error_model="numpy")
def two_encoder_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the two-encoder LQG for every lane (module doc)."""
    n = U.size
    EQ, XD, EV = X[EQ_ROW : EQ_ROW + 2], X[XD_ROW : XD_ROW + MAX_NX], X[EV_ROW : EV_ROW + MAX_NX]
    grid_equilibrium(X, C, n, EQ)
    correct(M, X, C, n, U, EQ, XD, EV)
    clip(U, n, C[U_MAX])
    predict(X, C, n, U, EQ, XD, EV)


def law_state(c) -> tuple[np.ndarray, np.ndarray] | None:
    """(state, constants) of the law of the reset :class:`controllers.two_encoder.TwoEncoderLQG` c (module doc);
    None for a design it does not hold."""
    nx = c._A.shape[1]  # the grid starts at its step (controllers.two_encoder.GRID)
    if nx > MAX_NX or nx < 6:
        return None
    X = np.zeros((N_ROWS, c.n))
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
    return np.ascontiguousarray(X), np.ascontiguousarray(C, dtype=np.float64)


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

    state = None if c.dyn is not None or c.compensates else law_state(c)
    return None if state is None else CompiledLaw(two_encoder_step, *state)
