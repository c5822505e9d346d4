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
compiled call (a chunk of periods) and the lanes stay laid out across periods.  At a period's start
``lanes_run`` resolves each lane's modes and takes its step-start slopes at the period's command on the scalar
path; here, without a lag or a delay in the composition, every lane's slopes are taken at once on the lanes
(as a lane step takes them at a changed command) and only a lane whose stuck disc's torque is not clear inside
its stick set (:data:`HOLD_MARGIN`) is resolved on the scalar path, which cuts the plant's cost per lane and
period by about 45 % on runs from rest; the runs agree with the reference to round-off (bit for bit in the
tests).  The first period of a call, and every period with a lag or a delay, starts every lane on the
scalar path as ``lanes_run`` does.  Specialised per composition of effects
(:meth:`drillgym.effects.codegen.CompiledModel.client`); compiled once whatever the law, which it takes as a
first-class function.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types

from drillgym.closed_loop.abi import LAW_TYPE, M_TL, M_TU, M_X, M_Y
from drillgym.dynamics import FREE_VIBRATION, UPPER, brake_on, lateral_free
from drillgym.kernels.commands import delay_line_step
from drillgym.kernels.hooks import (
    HAS_DELAY,
    HAS_LAG,
    N_STATE,
    hk_bounds_l_lane,
    hk_bounds_u_lane,
    hk_delay,
    hk_lane_params,
    hk_measure,
)
from drillgym.kernels.lane_steps import N_E, lane_derivative
from drillgym.kernels.lanes import ROWS_DIAG, ROWS_FULL, lane_start, lanes_commands, lanes_step
from drillgym.kernels.stepping import advance_batch, alloc_work
from drillgym.params import IDX
from drillgym.vmath import FASTMATH

__all__ = ["RUN_SIGNATURE", "run_periods", "OK", "NON_FINITE_COMMAND", "DIVERGED", "N_SIGNALS"]

TWO_PI = 2.0 * np.pi
OK, NON_FINITE_COMMAND, DIVERGED = 0, 1, 2
#: a stuck disc whose torque is within this fraction of its stick set's width from an edge restarts on the scalar
#: path (its modes resolved exactly as the reference resolves them)
HOLD_MARGIN = 1e-9
_Tcu, _dTcu, _Ts, _Tcl = IDX.Tcu, IDX.dTcu, IDX.Ts, IDX.Tcl
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
    """The sensors of lanes 0..n-1 into rows theta_u, theta_l, x, y of M (rad, m); no trigonometry for a lower disc
    at the centre (x, y 0: torsional runs)."""
    for k in range(n):
        y = Y[k]
        X = 0.0
        Yf = 0.0
        if y[4] != 0.0 or y[5] != 0.0:
            c, s = math.cos(y[0]), math.sin(y[0])
            X, Yf = y[4] * c - y[5] * s, y[4] * s + y[5] * c
        if has_meas:
            tu, tl, X, Yf = hk_measure(y[0], y[1], X, Yf, y[2], y[3], P[k])
        else:
            tu, tl = y[0], y[1]
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
def _start_lane(Y, MODE, UL, P, cfg, dt, T, HIST, HEAD, S, K1, FR, MU, ML, Ucur, Uprev, rows, k, y, mode, k1, fric):
    """Lane k of S started from its full state Y[k] and modes MODE[k] at the command UL[k] (V) through the delay
    line, as :func:`drillgym.kernels.lanes.lanes_run` starts it (scalar: modes resolved, step-start slopes)."""
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


@njit(cache=True)
def _restart_lanes(Y, MODE, UL, P, PT, cfg, dt, T, n, HIST, HEAD, S, K1, FR, MU, ML, EV, E, Ucur, Uprev, TT, rows,
                   y, mode, k1, fric):  # fmt: skip
    """The B lanes, laid out in S since the last period, restarted at the commands UL (V): the step-start slopes
    and friction of every lane at once (the lane right-hand side, as a lane step takes them at a changed command),
    then on the scalar path (:func:`_start_lane`, its modes resolved) each lane whose stuck disc may be released
    (:func:`_held`) and each padding lane (k >= n, a copy of lane n-1).  Without a lag or a delay (their start is
    per lane).  EV: work (B,)."""
    B = S.shape[1]
    full = lateral_free(cfg)
    fv = cfg == FREE_VIBRATION
    for k in range(B):
        Ucur[k] = UL[k, 0]
        Uprev[k] = Ucur[k]
        TT[k] = T[k]
    brake = brake_on(cfg)
    lane_derivative(S, MU, ML, Ucur, PT, full, 0.0 if cfg == UPPER else 1.0, brake, K1, FR, TT, 0.0, cfg, E)
    _held(S, FR, MU, ML, PT, full, brake, fv, cfg != UPPER, TT, EV)
    for k in range(B):
        if k >= n or EV[k] == 0:
            _start_lane(Y, MODE, UL, P, cfg, dt, T, HIST, HEAD, S, K1, FR, MU, ML, Ucur, Uprev, rows, k, y, mode, k1,
                        fric)  # fmt: skip


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _held(S, FR, MU, ML, PT, full, brake, fv, lower, TT, OK):
    """OK[k] = 1 where lane k's stuck discs hold their torques clear inside their stick sets (by more than
    :data:`HOLD_MARGIN` of the set's width), so that resolving its modes would keep them: the stick sets of
    :func:`drillgym.kernels.lane_steps.event_check` at the lanes' times TT; 0 where one may be released."""
    nm = 8 if full else 4
    hv = nm // 2
    bf = 1.0 if brake else 0.0
    Tcu, dTcu, Ts, Tcl = PT[_Tcu], PT[_dTcu], PT[_Ts], PT[_Tcl]
    for k in range(S.shape[1]):
        x = S[2, k] if full else 0.0
        yy = S[3, k] if full else 0.0
        vx = S[6, k] if full else 0.0
        vy = S[7, k] if full else 0.0
        thu, thl, wu, wl, t = S[0, k], S[1, k], S[hv, k], S[hv + 1, k], TT[k]
        lo_u, hi_u = hk_bounds_u_lane(-Tcu[k] + dTcu[k], Tcu[k] + dTcu[k], k, t, thu, thl, wu, wl, x, yy, vx, vy, S,
                                      nm, PT, 0.0)  # fmt: skip
        lim = Ts[k] if brake else Tcl[k]
        lo_l, hi_l = hk_bounds_l_lane(-lim, lim, k, t, thu, thl, wu, wl, x, yy, vx, vy, S, nm, PT, bf)
        fu, fl = FR[0, k], FR[1, k]
        gu = min(hi_u - fu, fu - lo_u) - HOLD_MARGIN * (hi_u - lo_u)
        gl = min(hi_l - fl, fl - lo_l) - HOLD_MARGIN * (hi_l - lo_l)
        gu = 1.0 if (MU[k] != 0.0 or fv) else gu
        gl = 1.0 if (ML[k] != 0.0 or not lower) else gl
        OK[k] = 1 if (gu > 0.0 and gl > 0.0) else 0


@njit(cache=True)
def _lane_period(Y, MODE, UL, P, PT, cfg, dt, T, sub, FRIC, HIST, HEAD, A, b, c, DM, S, S0, K1, FR, MU, ML, EV, W, E,
                 Ucur, Uprev, TT, y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1, n_real, laid_out):  # fmt: skip
    """One period of the B lanes held at the commands UL (V): :func:`drillgym.kernels.lanes.lanes_run` with
    ``n_steps = sub``, no record, the modes resolved as given; its work arrays (S ... TT, y ... g1), the
    parameter rows PT and the delays in steps DM given.  ``laid_out``: S holds the lanes since the last period
    (the first n_real real, the rest padding) and the composition has no lag or delay: the lanes restart in place
    (:func:`_restart_lanes`); else each lane starts on the scalar path, the same arithmetic in the same order."""
    B = Y.shape[0]
    full = lateral_free(cfg)
    rows = ROWS_FULL if full else ROWS_DIAG
    n = rows.shape[0]
    if laid_out and not HAS_LAG and not HAS_DELAY:
        _restart_lanes(Y, MODE, UL, P, PT, cfg, dt, T, n_real, HIST, HEAD, S, K1, FR, MU, ML, EV, E, Ucur, Uprev, TT,
                       rows, y, mode, k1, fric)  # fmt: skip
    else:
        for k in range(B):
            _start_lane(Y, MODE, UL, P, cfg, dt, T, HIST, HEAD, S, K1, FR, MU, ML, Ucur, Uprev, rows, k, y, mode, k1,
                        fric)  # fmt: skip
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
    """True when a state of lanes 0..n-1 is not finite or a speed beyond ``limit`` (rad/s); one flag over all the
    lanes (no exit inside the loop: it vectorises)."""
    bad = False
    for k in range(n):
        for j in range(min(N_STATE, 8)):
            bad |= not np.isfinite(Y[k, j])
        bad |= abs(Y[k, 2]) > limit or abs(Y[k, 3]) > limit
    return bad


@njit(cache=True)
def _clip_commands(U, UL, n, u_max):
    """The law's commands U (V) clipped to [-u_max, u_max] into U and the stepped lanes' UL; False when one is not
    finite."""
    ok = True
    for j in range(n):
        u = min(max(U[j], -u_max), u_max)
        ok &= np.isfinite(u)
        U[j] = u
        UL[j, 0] = u
    return ok


@njit(cache=True)
def _record(OUT, k, U, Y, MODE, FRIC, n):
    """Period k's signals of lanes 0..n-1 into OUT[:, k] (:data:`N_SIGNALS`): the command, the speeds, the
    winding, the lower disc's stick flag and friction, the lateral displacement (no hypot at the centre)."""
    for j in range(n):
        y_ = Y[j]
        OUT[0, k, j] = U[j]
        OUT[1, k, j] = y_[2]
        OUT[2, k, j] = y_[3]
        OUT[3, k, j] = y_[1] - y_[0]
        OUT[4, k, j] = 1.0 if MODE[j, 1] == 0 else 0.0
        OUT[5, k, j] = FRIC[j, 1]
        x, yy = y_[4], y_[5]
        OUT[6, k, j] = np.hypot(x, yy) if (x != 0.0 or yy != 0.0) else 0.0


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
    beyond which a run diverged (rad/s); ``OUT`` (7, total periods, n) the signals, row k0 + i (one
    contiguous store over the lanes per signal and period).
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
        if not _clip_commands(U, UL, n, u_max):
            return i, NON_FINITE_COMMAND
        _record(OUT, k, U, Y, MODE, FRIC, n)
        if lanes:
            _pad(Y, MODE, UL, T, FRIC, HIST, HEAD, n)
            _lane_period(Y, MODE, UL, P, PT, cfg, dt, T, sub, FRIC, HIST, HEAD, A, b, c, DM, S, S0, K1, FR, MU, ML, EV,
                         W, E, Ucur, Uprev, TT, y, mode, K, ytmp, k1, ynew, fric, ftmp, g0, g1, n, i > 0)  # fmt: skip
        else:
            advance_batch(Y, MODE, UL[:, 0].copy(), P, cfg, dt, sub, T, eps, A, b, c, FRIC, HIST, HEAD)
        if _diverged(Y, n, limit):
            return i + 1, DIVERGED
    return m, OK
