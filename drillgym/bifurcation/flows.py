"""Client kernel template: flows of the rig to a Poincare section on the exact event-driven integrator.

Specialised per composition of effects (:meth:`drillgym.effects.codegen.CompiledModel.client`),
so the section map integrates the same compiled model as :func:`drillgym.simulate`.  Used by
:class:`drillgym.bifurcation.poincare.SectionMap`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from drillgym.bifurcation.summary import F_OK, F_R_MAX, F_R_MIN, F_STICK, F_T, F_WL_MAX, F_WL_MIN, N_SUMMARY
from drillgym.dynamics import S_WL, S_X, S_Y
from drillgym.kernels.hooks import N_STATE
from drillgym.kernels.model import initial_modes
from drillgym.kernels.stepping import alloc_work, copy_step_state, hybrid_step

REFINE_ITERATIONS = 30


@njit(cache=True)
def flow_to_section(y, u, ws, p, cfg, dt, t_max, A, b, c):
    """Integrate from state ``y`` (on or off the section) to the next upward crossing of omega_l = ws.

    ``y`` is overwritten by the state at the crossing.  Returns a summary
    vector (ok, return time, min/max omega_l, min/max r, stuck time of the lower disc).
    """
    out = np.zeros(N_SUMMARY)
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    mode = np.zeros(2, dtype=np.int64)
    ys = np.zeros(N_STATE)
    ks = np.zeros(N_STATE)
    fs = np.zeros(2)
    ms = np.zeros(2, dtype=np.int64)
    t = 0.0
    initial_modes(t, y, u, p, cfg, mode, k1, fric)
    armed = False
    wl_min = y[S_WL]
    wl_max = y[S_WL]
    r0 = math.sqrt(y[S_X] ** 2 + y[S_Y] ** 2)
    r_min = r0
    r_max = r0
    stick = 0.0
    n_max = int(t_max / dt) + 1
    for _ in range(n_max):
        copy_step_state(y, k1, fric, mode, ys, ks, fs, ms)  # snapshot: the crossing is re-stepped from here
        gprev = y[S_WL] - ws
        hybrid_step(t, y, k1, fric, mode, u, p, cfg, 0.0, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
        gnew = y[S_WL] - ws
        if mode[1] == 0:
            stick += dt
        if gnew < 0.0:
            armed = True
        elif armed and gprev < 0.0:
            # locate the crossing inside this step (Illinois on the step fraction)
            ta, ga, tb, gb = 0.0, gprev, 1.0, gnew
            side = 0
            tau = 1.0
            for _it in range(REFINE_ITERATIONS):
                tau = (ta * gb - tb * ga) / (gb - ga)
                copy_step_state(ys, ks, fs, ms, y, k1, fric, mode)
                hybrid_step(t, y, k1, fric, mode, u, p, cfg, 0.0, tau * dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
                gt = y[S_WL] - ws
                if abs(gt) < 1e-13 or (tb - ta) < 1e-15:
                    break
                if gt > 0.0:
                    tb, gb = tau, gt
                    if side == 1:
                        ga *= 0.5
                    side = 1
                else:
                    ta, ga = tau, gt
                    if side == -1:
                        gb *= 0.5
                    side = -1
            t += tau * dt
            out[F_OK] = 1.0
            out[F_T] = t
            break
        t += dt
        w = y[S_WL]
        if w < wl_min:
            wl_min = w
        if w > wl_max:
            wl_max = w
        r = math.sqrt(y[S_X] ** 2 + y[S_Y] ** 2)
        if r < r_min:
            r_min = r
        if r > r_max:
            r_max = r
    out[F_WL_MIN] = wl_min
    out[F_WL_MAX] = wl_max
    out[F_R_MIN] = r_min
    out[F_R_MAX] = r_max
    out[F_STICK] = stick
    return out


@njit(cache=True, parallel=True)
def flow_batch(Y, U, WS, P, cfg, dt, t_max, A, b, c, OUT):
    """flow_to_section for every row of Y (B, N_STATE) in parallel; Y overwritten, OUT (B, N_SUMMARY)."""
    for k in prange(Y.shape[0]):
        OUT[k] = flow_to_section(Y[k], U[k], WS[k], P[k], cfg, dt, t_max, A, b, c)
