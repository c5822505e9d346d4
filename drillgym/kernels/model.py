"""Kernel template: the right-hand side, friction laws and switching logic of one composition.

The base model is that of docs/model.md (equations in :mod:`drillgym.dynamics`, friction laws in
:mod:`drillgym.friction`); the composition's effects enter only through the hooks of
:mod:`drillgym.kernels.hooks` (replaced by the generated module when this template is
specialised, see :mod:`drillgym.effects.codegen`).

``state_derivative(t, y, mode, u, p, cfg, smooth_eps, dy, fric)``: mode = int64[2] (upper, lower),
+1/-1 slipping, 0 stuck.  A stuck disc contributes the unknown friction torque that keeps its
acceleration zero (the Lagrange-multiplier form of the switch model); it is returned in ``fric``
so the integrator releases the disc when it leaves the stick set.  ``u`` is the commanded
voltage after any transport delay; Input effects turn it into the motor's voltage.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from drillgym.dynamics import (
    FREE_VIBRATION,
    S_TL,
    S_TU,
    S_VX,
    S_VY,
    S_WL,
    S_WU,
    S_X,
    S_Y,
    UPPER,
    brake_on,
    full_accelerations,
    isotropic_lateral_forces,
    lateral_free,
    reduced_accelerations,
)
from drillgym.friction import bearing_law, brake_law, upper_law
from drillgym.kernels.hooks import (
    N_STATE,
    hk_bounds_l,
    hk_bounds_u,
    hk_rhs,
    hk_slip_l,
    hk_slip_u,
)
from drillgym.params import IDX
from drillgym.vmath import FASTMATH

_Ju, _km, _Jl, _kth = IDX.Ju, IDX.km, IDX.Jl, IDX.ktheta
_mr, _mt, _k, _b, _e = IDX.mr, IDX.mt, IDX.k, IDX.b, IDX.e
_Tcu, _dTcu, _bu, _dbu = IDX.Tcu, IDX.dTcu, IDX.bu, IDX.dbu
_Tcl, _bl = IDX.Tcl, IDX.bl
_Ts, _Tc, _ws, _delta, _bb = IDX.Ts, IDX.Tc, IDX.ws, IDX.delta, IDX.bb


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def upper_slip_torque(w, d, t, y, p):
    """Upper friction torque (N m) while slipping in direction d (+1.0/-1.0, a float: one compiled version)."""
    T = upper_law(abs(w), float(d), p[_Tcu], p[_dTcu], p[_bu], p[_dbu])
    return hk_slip_u(T, float(d), abs(w), t, y, p, 0.0)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def lower_slip_torque(w, d, t, y, p, brake):
    """Lower friction torque (N m) while slipping in direction d (+1.0/-1.0; brake: Stribeck law, else bearing)."""
    aw = abs(w)
    if brake:
        T = brake_law(aw, float(d), p[_Ts], p[_Tc], p[_ws], p[_delta], p[_bb])
    else:
        T = bearing_law(aw, float(d), p[_Tcl], p[_bl])
    return hk_slip_l(T, float(d), aw, t, y, p, 1.0 if brake else 0.0)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def upper_stick_bounds(t, y, p):
    """Stick set of the upper disc (N m): (lo, hi)."""
    return hk_bounds_u(-p[_Tcu] + p[_dTcu], p[_Tcu] + p[_dTcu], t, y, p, 0.0)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def lower_stick_bounds(t, y, p, brake):
    """Stick set of the lower disc (N m): (lo, hi)."""
    lim = p[_Ts] if brake else p[_Tcl]
    return hk_bounds_l(-lim, lim, t, y, p, 1.0 if brake else 0.0)


@njit(cache=True, fastmath=FASTMATH, _nrt=False)
def state_derivative(t, y, mode, u, p, cfg, smooth_eps, dy, fric):
    """dy/dt of the state for constant command u (V) and friction modes ``mode``.

    Writes the friction torques (Tfu, Tfl) in N m into ``fric`` (for a stuck disc: the
    constraint torque).  ``smooth_eps`` > 0 selects the explicit smoothed friction option
    (sign -> tanh(w/eps), modes ignored).
    """
    for i in range(dy.shape[0]):
        dy[i] = 0.0
    wu = y[S_WU]
    wl = y[S_WL]
    brake = brake_on(cfg)
    volt, Qe_u, Qe_l, Qe_s, Qe_x, Qe_y = hk_rhs(t, u, y, p, cfg, dy)
    torque = p[_km] * volt + Qe_u
    dy[S_TU] = wu
    dy[S_TL] = wl
    mu = mode[0]
    ml = mode[1]
    if smooth_eps > 0.0:
        su = math.tanh(wu / smooth_eps)
        sl = math.tanh(wl / smooth_eps)
        tfu = su * upper_slip_torque(wu, 1.0, t, y, p) if su >= 0 else -su * upper_slip_torque(wu, -1.0, t, y, p)
        tfl = (
            sl * lower_slip_torque(wl, 1.0, t, y, p, brake)
            if sl >= 0
            else -sl * lower_slip_torque(wl, -1.0, t, y, p, brake)
        )
        mu = 2  # "slipping, torque given"
        ml = 2
    else:
        tfu = upper_slip_torque(wu, float(mu), t, y, p) if mu != 0 else 0.0
        tfl = lower_slip_torque(wl, float(ml), t, y, p, brake) if ml != 0 else 0.0
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
    string = p[_kth] * alpha + Qe_s  # torque of the string on the upper disc (N m)

    if not lateral_free(cfg):
        a_u, a_l, fu, fl = reduced_accelerations(torque, string, Qe_l, tfu, tfl, p[_Ju], p[_Jl], mu != 0, ml != 0)
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
    Qu, Qx, Qy = isotropic_lateral_forces(x, yy, vx, vy, wu, p[_k], p[_b])
    s = math.sin(alpha)
    c = math.cos(alpha)
    a_u, a_l, a_x, a_y, fu, fl = full_accelerations(
        x,
        yy,
        vx,
        vy,
        wu,
        wl,
        s,
        c,
        p[_mr] + p[_mt],
        p[_e] * p[_mr],
        p[_Ju],
        p[_Jl],
        torque,
        string,
        Qe_l,
        tfu,
        tfl,
        Qu,
        Qx + Qe_x,
        Qy + Qe_y,
        mu != 0,
        ml != 0,
    )
    dy[S_WU] = a_u
    dy[S_WL] = a_l
    dy[S_X] = vx
    dy[S_Y] = vy
    dy[S_VX] = a_x
    dy[S_VY] = a_y
    fric[0] = fu
    fric[1] = fl


@njit(cache=True, _nrt=False)
def event_values(t, y, mode, fric, p, cfg, g):
    """Event functions (positive while the current modes are consistent)."""
    if cfg == FREE_VIBRATION:
        g[0] = 1.0
    elif mode[0] != 0:
        g[0] = mode[0] * y[S_WU]
    else:
        lo, hi = upper_stick_bounds(t, y, p)
        g[0] = min(hi - fric[0], fric[0] - lo)
    if cfg == UPPER:
        g[1] = 1.0
    elif mode[1] != 0:
        g[1] = mode[1] * y[S_WL]
    else:
        lo, hi = lower_stick_bounds(t, y, p, brake_on(cfg))
        g[1] = min(hi - fric[1], fric[1] - lo)


@njit(cache=True, _nrt=False)
def resolve_modes(t, y, mode, u, p, cfg, dy, fric):
    """Make the modes consistent at (t, y): discs with w = 0 and mode 0 stay stuck if their
    holding torque lies in the stick set, else they start slipping in the direction of
    the excess.  Leaves dy, fric evaluated with the final modes."""
    for _ in range(4):
        state_derivative(t, y, mode, u, p, cfg, 0.0, dy, fric)
        changed = False
        if mode[0] == 0 and cfg != FREE_VIBRATION:
            lo, hi = upper_stick_bounds(t, y, p)
            if fric[0] > hi:
                mode[0] = 1
                changed = True
            elif fric[0] < lo:
                mode[0] = -1
                changed = True
        if mode[1] == 0 and cfg != UPPER:
            lo, hi = lower_stick_bounds(t, y, p, brake_on(cfg))
            if fric[1] > hi:
                mode[1] = 1
                changed = True
            elif fric[1] < lo:
                mode[1] = -1
                changed = True
        if not changed:
            return


@njit(cache=True, _nrt=False)
def initial_modes(t, y, u, p, cfg, mode, dy, fric):
    """Modes from the initial state: sign of the speed, or stuck (then resolved) at zero speed."""
    mode[0] = 0 if y[S_WU] == 0.0 else (1 if y[S_WU] > 0 else -1)
    mode[1] = 0 if y[S_WL] == 0.0 else (1 if y[S_WL] > 0 else -1)
    if cfg == UPPER:
        mode[1] = 0
    if cfg == FREE_VIBRATION:
        mode[0] = 0
        y[S_WU] = 0.0
    resolve_modes(t, y, mode, u, p, cfg, dy, fric)


@njit(cache=True, _nrt=False)
def record(out, row, t, u, y, fric, mode, cols=None):
    """Write one output sample: all of the composition's OUTPUT_NAMES (the 18 base columns, then the
    effects' states), or only the columns ``cols`` (indices into them, in that order); the lateral
    trigonometry only when x, y or r is recorded."""
    need_xy = cols is None
    if cols is not None:
        for j in range(cols.shape[0]):
            if 11 <= cols[j] <= 13:
                need_xy = True
    X = 0.0
    Y = 0.0
    if need_xy:
        ct = np.cos(y[S_TU])
        st = np.sin(y[S_TU])
        X = y[S_X] * ct - y[S_Y] * st
        Y = y[S_X] * st + y[S_Y] * ct
    if cols is None:
        for c in range(10 + N_STATE):
            out[row, c] = _output_value(c, t, u, y, fric, mode, X, Y)
    else:
        for j in range(cols.shape[0]):
            out[row, j] = _output_value(cols[j], t, u, y, fric, mode, X, Y)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _output_value(c, t, u, y, fric, mode, X, Y):
    """Output column c (see OUTPUT_NAMES) of a sample; X, Y the fixed-frame lateral position (m),
    computed by the caller when x, y or r is recorded."""
    if c == 0:
        return t
    if c == 1:
        return u
    if c < 10:
        return y[c - 2]
    if c == 10:
        return y[S_TL] - y[S_TU]
    if 11 <= c <= 13:
        return X if c == 11 else (Y if c == 12 else np.sqrt(X * X + Y * Y))
    if c == 14:
        return fric[0]
    if c == 15:
        return fric[1]
    if c == 16:
        return 1.0 if mode[0] == 0 else 0.0
    if c == 17:
        return 1.0 if mode[1] == 0 else 0.0
    return y[c - 10]  # the effects' states (column 18 + j <- state 8 + j)
