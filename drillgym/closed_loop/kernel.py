"""Client kernel template: control periods of a batch of plants and a compiled law, in one compiled call.

Per control period and for every lane: the sensors (the composition's Measurement effects, encoder
quantization to ``counts_per_rev``, white angle noise drawn by the caller), the law
(:mod:`drillgym.closed_loop.abi`), the recorded signals, then the plant held at the law's command over
``sub`` integration steps with the composition's own kernels, exactly as
:meth:`drillgym.BatchSimulator.advance` steps them: the SIMD lane steps on whole blocks of lanes (the
lanes past the last real one step beside it as its copies), or the scalar ``advance_batch`` for batches
smaller than :data:`drillgym.lane_runner.LANES_MIN_BATCH`.

The lane path is :func:`drillgym.kernels.lanes.lanes_run` called once per period, without what that call
sets up anew each time: its work arrays, the transposed parameter rows and the delays are made once per
compiled call (a chunk of periods) and the lanes stay laid out across periods.  What the plant's state
implies is still worked out per period as ``lanes_run`` does (each lane's modes resolved and its
step-start slopes taken at the new command on the scalar path), so the runs are the reference's bit for
bit.  Specialised per composition of effects (:meth:`drillgym.effects.codegen.CompiledModel.client`);
compiled once whatever the law, which it takes as a first-class function.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from drillgym.closed_loop.abi import LAW_TYPE, M_TL, M_TU, M_X, M_Y
from drillgym.dynamics import lateral_free
from drillgym.kernels.commands import delay_line_step
from drillgym.kernels.hooks import HAS_DELAY, N_STATE, hk_delay, hk_lane_params, hk_measure
from drillgym.kernels.lane_steps import N_E
from drillgym.kernels.lanes import ROWS_DIAG, ROWS_FULL, lane_start, lanes_commands, lanes_step
from drillgym.kernels.stepping import advance_batch, alloc_work

__all__ = ["RUN_SIGNATURE", "run_periods", "OK", "NON_FINITE_COMMAND", "DIVERGED", "N_SIGNALS"]

TWO_PI = 2.0 * np.pi
OK, NON_FINITE_COMMAND, DIVERGED = 0, 1, 2
N_SIGNALS = 7  # u, omega_u, omega_l, alpha, stuck_l, friction_l, r

_F1, _F2, _F3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
_I1, _I2 = types.int64[::1], types.int64[:, ::1]
_I, _F, _B = types.int64, types.float64, types.boolean
RUN_SIGNATURE = types.UniTuple(_I, 2)(
    LAW_TYPE, _F2, _F1, _F1, _F2, _F2, _F2, _I2, _F2, _I, _F, _I, _F1, _F, _F2, _F1, _F1, _F2, _F2, _I1, _F3,
    _I, _B, _B, _I, _I, _F, _F1, _F1, _F3, _B, _B, _F, _F, _F3,
)  # fmt: skip


@njit(cache=True)
def _encoder(theta, cpr):
    """The angle an encoder of ``cpr`` counts/rev reports (rad; cpr 0: exact), as the reference runner."""
    if cpr > 0:
        return math.floor(theta * (cpr / TWO_PI)) * (TWO_PI / cpr) + 0.0
    return theta


@njit(cache=True)
def _measure(Y, P, n, has_meas, cpr, noise, Z, i, noisy, M):
    """The sensors of lanes 0..n-1 into rows theta_u, theta_l, x, y of M (rad, m)."""
    for k in range(n):
        y = Y[k]
        X = 0.0
        Yf = 0.0
        if has_meas:
            if y[4] != 0.0 or y[5] != 0.0:
                c, s = math.cos(y[0]), math.sin(y[0])
                X, Yf = y[4] * c - y[5] * s, y[4] * s + y[5] * c
            tu, tl, X, Yf = hk_measure(y[0], y[1], X, Yf, y[2], y[3], P[k])
        else:
            tu, tl = y[0], y[1]
            c, s = math.cos(y[0]), math.sin(y[0])
            X, Yf = y[4] * c - y[5] * s, y[4] * s + y[5] * c
        qu = _encoder(tu, cpr[k])
        ql = _encoder(tl, cpr[k])
        if noisy:
            qu = qu + Z[i, 0, k] * noise[k]
            ql = ql + Z[i, 1, k] * noise[k]
        M[M_TU, k] = qu
        M[M_TL, k] = ql
        M[M_X, k] = X
        M[M_Y, k] = Yf


@njit(cache=True)
def _pad(Y, MODE, UL, T, FRIC, HIST, HEAD, n):
    """Lanes n.. as copies of lane n-1 (as :func:`drillgym.lane_runner.pad_lanes` before every call)."""
    last = n - 1
    for k in range(n, Y.shape[0]):
        Y[k, :] = Y[last, :]
        MODE[k, :] = MODE[last, :]
        UL[k, 0] = UL[last, 0]
        T[k] = T[last]
        FRIC[k, :] = FRIC[last, :]
        HIST[k, :] = HIST[last, :]
        HEAD[k] = HEAD[last]


@njit(cache=True)
def _lane_period(Y, MODE, UL, P, PT, cfg, dt, T, sub, FRIC, HIST, HEAD, A, b, c, DM, S, S0, K1, FR, MU, ML, EV, W, E,
                 Ucur, Uprev, TT, y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1):  # fmt: skip
    """One period of the B lanes held at the commands UL (V): :func:`drillgym.kernels.lanes.lanes_run` with
    ``n_steps = sub``, no record, the modes resolved as given; its work arrays (S ... TT, y ... g1), the
    parameter rows PT and the delays in steps DM given.  The same arithmetic in the same order."""
    B = Y.shape[0]
    full = lateral_free(cfg)
    rows = ROWS_FULL if full else ROWS_DIAG
    n = rows.shape[0]
    for k in range(B):
        for j in range(N_STATE):
            y[j] = Y[k, j]
        for j in range(2):
            mode[j] = MODE[k, j]
        u0 = delay_line_step(HIST[k], HEAD[k : k + 1], UL[k, 0], P[k], dt)
        lane_start(T[k], y, mode, u0, P[k], cfg, False, S, K1, FR, MU, ML, rows, k, k1, fric)
        for j in range(N_STATE):
            Y[k, j] = y[j]
        Uprev[k] = u0
        Ucur[k] = u0
    for i in range(sub):
        new_input = lanes_commands(i, dt, T, UL, 0, HIST, HEAD, DM, Ucur, Uprev, TT)
        lanes_step(new_input, Y, P, PT, cfg, dt, A, b, c, rows, S, S0, K1, FR, MU, ML, EV, W, E, Ucur, Uprev, TT,
                   y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1)  # fmt: skip
    for k in range(B):
        for j in range(n):
            Y[k, rows[j]] = S[j, k]
        MODE[k, 0] = np.int64(MU[k])
        MODE[k, 1] = np.int64(ML[k])
        FRIC[k, 0] = FR[0, k]
        FRIC[k, 1] = FR[1, k]
        T[k] += sub * dt


@njit(cache=True)
def _diverged(Y, n, limit):
    for k in range(n):
        for j in range(min(N_STATE, 8)):
            if not np.isfinite(Y[k, j]):
                return True
        if abs(Y[k, 2]) > limit or abs(Y[k, 3]) > limit:
            return True
    return False


@njit(RUN_SIGNATURE, cache=True)
def run_periods(
    law, X, C, U, M, UL, Y, MODE, P, cfg, dt, sub, T, eps, A, b, c, FRIC, HIST, HEAD, NOREC,
    n, lanes, has_meas, k0, m, ctrl_dt, cpr, noise, Z, noisy, first_given, u_max, limit, OUT,
):  # fmt: skip
    """Control periods k0 .. k0+m-1 of n lanes (module doc); returns (periods done, status).

    ``X``, ``C``: the law's state and constants; ``U`` (n,) its commands (V), ``M`` (5, n) its measurements
    (row omega_ref set by the caller; with ``first_given`` the measurement of period k0 too); ``UL`` (B, 1)
    the commands of the B stepped lanes; ``Y`` ... ``HEAD`` the plant (B lanes, :class:`BatchSimulator`'s
    arrays); ``NOREC`` the lane kernel's empty record; ``cpr``, ``noise`` (n,) the encoders' counts/rev and
    the angle noise (rad); ``Z`` (m, 2, n) standard normal draws for theta_u, theta_l; ``limit`` the speed
    beyond which a run diverged (rad/s); ``OUT`` (7, n, total periods) the signals, column k0 + i.
    Status: OK, NON_FINITE_COMMAND (the period's command is not finite: nothing recorded) or DIVERGED
    (a state is not finite or a speed beyond ``limit`` after the period)."""
    B = Y.shape[0]
    nr = (ROWS_FULL if lateral_free(cfg) else ROWS_DIAG).shape[0]
    PT = hk_lane_params(P)  # the lane path's work arrays, once per call (lanes_run makes them per period)
    S, S0, K1 = np.empty((nr, B)), np.empty((nr, B)), np.zeros((nr, B))
    FR, MU, ML, EV = np.zeros((2, B)), np.zeros(B), np.zeros(B), np.zeros(B, dtype=np.int64)
    W, E = np.zeros((max(4, b.shape[0]) * nr, B)), np.zeros((N_E + 1, B))
    Ucur, Uprev, TT = np.empty(B), np.empty(B), np.empty(B)
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    y, mode = np.zeros(N_STATE), np.zeros(2, dtype=np.int64)
    DM = np.zeros(B)  # each lane's delay in steps (a Delay effect)
    if HAS_DELAY:
        for j in range(B):
            DM[j] = max(hk_delay(P[j]), 0.0) / dt
    for i in range(m):
        k = k0 + i
        if not (first_given and i == 0):
            _measure(Y, P, n, has_meas, cpr, noise, Z, i, noisy, M)
        law(k * ctrl_dt, M, X, C, U)
        for j in range(n):
            u = min(max(U[j], -u_max), u_max)
            if not np.isfinite(u):
                return i, NON_FINITE_COMMAND
            U[j] = u
            UL[j, 0] = u
            y_ = Y[j]
            OUT[0, j, k] = u
            OUT[1, j, k] = y_[2]
            OUT[2, j, k] = y_[3]
            OUT[3, j, k] = y_[1] - y_[0]
            OUT[4, j, k] = 1.0 if MODE[j, 1] == 0 else 0.0
            OUT[5, j, k] = FRIC[j, 1]
            OUT[6, j, k] = np.hypot(y_[4], y_[5])
        if lanes:
            _pad(Y, MODE, UL, T, FRIC, HIST, HEAD, n)
            _lane_period(Y, MODE, UL, P, PT, cfg, dt, T, sub, FRIC, HIST, HEAD, A, b, c, DM, S, S0, K1, FR, MU, ML, EV,
                         W, E, Ucur, Uprev, TT, y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1)  # fmt: skip
        else:
            advance_batch(Y, MODE, UL[:, 0].copy(), P, cfg, dt, sub, T, eps, A, b, c, FRIC, HIST, HEAD)
        if _diverged(Y, n, limit):
            return i + 1, DIVERGED
    return m, OK
