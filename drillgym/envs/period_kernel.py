"""Client kernel template: one control period of n rigs as ONE compiled call.

The composition's ``advance_batch`` (voltage held over the sub-steps, all rigs), then per rig
the reward (:mod:`.reward`), the stick-slip severity and safety limits (:mod:`.task`) and, in
'full' mode, the observation (:mod:`.observation`).  Specialised per composition of effects
(:meth:`drillgym.effects.codegen.CompiledModel.client`), so every rig runs the same compiled
model as :func:`drillgym.simulate`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.envs.columns import (
    C_REF,
    C_REW,
    C_SSI,
    C_STEPS,
    C_STUCK,
    C_TERM,
    C_TFL,
    C_TIME,
    C_TRUNC,
    C_U,
    C_WL,
    T_BLOCK,
    T_BOUNDS,
    T_DT,
    T_FULL,
    T_LAT,
    T_LATERAL,
    T_SPEED,
    T_STEPS,
    T_W,
    TERM_LIMIT,
    TERM_NONE,
    TERM_NONFINITE,
)
from drillgym.envs.observation import full_obs_row
from drillgym.envs.reward import reward_value
from drillgym.envs.task import ssi_push, unsafe_row
from drillgym.kernels.stepping import advance_batch

__all__ = ["period_kernel"]


@njit(cache=True)
def period_kernel(Y, MODE, u, P, cfg, dt, n_sub, T, eps, A, b, c, FRIC, HIST, HEAD, S, W, C, tv, OBS):
    """One control period of every rig: the core's advance_batch, then per rig reward, SSI,
    limits, episode length and (full mode) the observation.  S: (n, len(S_COLUMNS)); W, C: the
    StickSlipMonitor arrays; tv: task constants (T_* layout, observation bounds at the end).

    A rig whose state is no longer finite (an effect's formula gave NaN or inf) is terminated
    (``TERM_NONFINITE``) and keeps its last finite reward, speed, friction, stick flag, severity
    and observation."""
    advance_batch(Y, MODE, u, P, cfg, dt, n_sub, T, eps, A, b, c, FRIC, HIST, HEAD)
    rw = tv[T_W : T_W + 4]
    lateral = tv[T_LATERAL] > 0.0
    block_len = int(tv[T_BLOCK])
    full_obs = tv[T_FULL] > 0.0
    dim = OBS.shape[1]
    low = tv[T_BOUNDS : T_BOUNDS + dim]
    high = tv[T_BOUNDS + dim : T_BOUNDS + 2 * dim]
    for k in range(Y.shape[0]):
        y = Y[k]
        Sk = S[k]
        finite = True
        for i in range(y.shape[0]):
            if not np.isfinite(y[i]):
                finite = False
        if not finite:
            Sk[C_U] = u[k]
            Sk[C_STEPS] += 1.0
            Sk[C_TIME] = Sk[C_STEPS] * tv[T_DT]
            Sk[C_TERM] = TERM_NONFINITE
            Sk[C_TRUNC] = 1.0 if Sk[C_STEPS] >= tv[T_STEPS] else 0.0
            continue
        stuck = MODE[k, 1] == 0
        Sk[C_REW] = reward_value(y[3], Sk[C_REF], stuck, u[k], Sk[C_U], rw)
        Sk[C_U] = u[k]
        Sk[C_SSI] = ssi_push(y[3], W[k, 0], W[k, 1], W[k, 2], C[k], block_len)
        Sk[C_WL] = y[3]
        Sk[C_TFL] = FRIC[k, 1]
        Sk[C_STUCK] = 1.0 if stuck else 0.0
        Sk[C_STEPS] += 1.0
        Sk[C_TIME] = Sk[C_STEPS] * tv[T_DT]
        Sk[C_TERM] = TERM_LIMIT if unsafe_row(y, tv[T_SPEED], tv[T_LAT], lateral) else TERM_NONE
        Sk[C_TRUNC] = 1.0 if Sk[C_STEPS] >= tv[T_STEPS] else 0.0
        if full_obs:
            full_obs_row(y, u[k], Sk[C_REF], lateral, low, high, OBS[k])
