"""Fixed-step Runge-Kutta integration with exact, event-driven stick-slip.

Two explicit tableaus: classical RK4 and Dormand-Prince 5 (the 5th-order
solution of DOPRI5, MATLAB's ``ode5``: a cost that is smooth in the parameters
for identification).  Both run on a fixed grid of step ``dt``; the default
``DEFAULT_DT = 1 ms`` resolves the fastest mode of the coupled rig (lateral,
15 rad/s, period 0.42 s) with >400 steps per period and keeps RK4's error on
the stick-slip cycle below 1e-6 rad/s (tests compare against dt/4).

Set-valued friction is treated exactly with a hybrid (event-driven) scheme
inside each fixed step, the approach of Leine's switch model made exact:

* every disc is in a discrete mode: slipping +1 / -1 (smooth friction law with
  that sign) or stuck 0 (speed exactly zero, friction = the constraint torque
  lambda that keeps it at rest);
* after a step, event functions are checked: a slipping disc's signed speed
  ``d w`` and a stuck disc's margin to its stick set ``min(hi - lambda, lambda - lo)``;
* when one changes sign, the event time inside the step is located by the
  Illinois method (re-stepping from the step's start), the state is advanced
  to it, the mode switched (a disc reaching w = 0 sticks if the torque needed
  to hold it lies in its stick set, otherwise it reverses), and the rest of
  the step is integrated with the new modes.

So a stuck disc stays at exactly zero speed for as long as the holding torque
stays in the stick set, and releases when (to the located event time) it leaves.
Outputs stay on the fixed grid.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .configurations import N_STATE
from .dynamics import FREE_VIBRATION, UPPER, lateral_free, S_TL, S_TU, S_WL, S_WU, S_X, S_Y, brake_on, state_derivative
from .friction import lower_stick_bounds, upper_stick_bounds
from .params import IDX

_TAU_M = IDX.tau_m

DEFAULT_DT = 1e-3  # s
MAX_EVENTS_PER_STEP = 8
ILLINOIS_ITERATIONS = 6

# Butcher tableaus ---------------------------------------------------------------
RK4_A = np.array([[0.0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1.0, 0]])
RK4_B = np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6])
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])

DP5_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
], dtype=np.float64)
DP5_B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
DP5_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])

TABLEAUS = {"rk4": (RK4_A, RK4_B, RK4_C), "dp5": (DP5_A, DP5_B, DP5_C)}

# output columns of a recorded sample ---------------------------------------------
OUTPUT_NAMES = ("t", "u", "theta_u", "theta_l", "omega_u", "omega_l", "x_rot", "y_rot", "vx_rot", "vy_rot",
                "u_m", "alpha", "x", "y", "r", "Tfu", "Tfl", "stick_u", "stick_l")
N_OUT = len(OUTPUT_NAMES)


def tableau(method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, b, c) of 'rk4' or 'dp5'."""
    try:
        return TABLEAUS[method.lower()]
    except KeyError:
        raise ValueError(f"unknown integration method {method!r}; expected 'rk4' or 'dp5'") from None


@njit(cache=True)
def alloc_work(n_stages: int):
    """Work arrays of ``hybrid_step`` for a tableau of n_stages:
    (K stage derivatives + end derivative, ytmp, k1, ynew, fric, ftmp, g0, g1)."""
    K = np.zeros((n_stages + 1, N_STATE))
    return (K, np.zeros(N_STATE), np.zeros(N_STATE), np.zeros(N_STATE), np.zeros(2), np.zeros(2), np.zeros(2),
            np.zeros(2))


@njit(cache=True, _nrt=False)
def active_states(cfg, p):
    """Number of leading state entries that evolve: 4 (angles, speeds) unless the disc moves
    laterally or the motor_lag state is on (then all N_STATE)."""
    if lateral_free(cfg) or p[_TAU_M] > 0.0:
        return N_STATE
    return 4


@njit(cache=True, fastmath=True, _nrt=False)
def _rk_step(t, y0, k1, mode, u, p, cfg, eps, h, A, b, c, K, ytmp, y_out, fric):
    """One explicit RK step of size h from (t, y0) with derivative k1 at y0; result in y_out.

    Only the first ``active_states`` entries evolve; the others are copied.  The
    4-stage tableau (classical RK4, sparse) takes an unrolled path, the others
    (DP5) the general Butcher loop.
    """
    s = b.shape[0]
    n = active_states(cfg, p)
    for j in range(n, y0.shape[0]):
        ytmp[j] = y0[j]
        y_out[j] = y0[j]
    if s == 4:
        k2 = K[1]
        k3 = K[2]
        k4 = K[3]
        hh = 0.5 * h
        for j in range(n):
            ytmp[j] = y0[j] + hh * k1[j]
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k2, fric)
        for j in range(n):
            ytmp[j] = y0[j] + hh * k2[j]
        state_derivative(t + hh, ytmp, mode, u, p, cfg, eps, k3, fric)
        for j in range(n):
            ytmp[j] = y0[j] + h * k3[j]
        state_derivative(t + h, ytmp, mode, u, p, cfg, eps, k4, fric)
        h6 = h / 6.0
        for j in range(n):
            y_out[j] = y0[j] + h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
        return
    for j in range(n):
        K[0, j] = k1[j]
    for i in range(1, s):
        for j in range(n):
            acc = 0.0
            for l in range(i):
                acc += A[i, l] * K[l, j]
            ytmp[j] = y0[j] + h * acc
        state_derivative(t + c[i] * h, ytmp, mode, u, p, cfg, eps, K[i], fric)
    for j in range(n):
        acc = 0.0
        for i in range(s):
            acc += b[i] * K[i, j]
        y_out[j] = y0[j] + h * acc


@njit(cache=True, _nrt=False)
def event_values(t, y, mode, fric, p, cfg, g):
    """Event functions (positive while the current modes are consistent)."""
    if cfg == FREE_VIBRATION:
        g[0] = 1.0
    elif mode[0] != 0:
        g[0] = mode[0] * y[S_WU]
    else:
        lo, hi = upper_stick_bounds(p)
        g[0] = min(hi - fric[0], fric[0] - lo)
    if cfg == UPPER:
        g[1] = 1.0
    elif mode[1] != 0:
        g[1] = mode[1] * y[S_WL]
    else:
        lo, hi = lower_stick_bounds(y[S_TL], t, p, brake_on(cfg))
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
            lo, hi = upper_stick_bounds(p)
            if fric[0] > hi:
                mode[0] = 1
                changed = True
            elif fric[0] < lo:
                mode[0] = -1
                changed = True
        if mode[1] == 0 and cfg != UPPER:
            lo, hi = lower_stick_bounds(y[S_TL], t, p, brake_on(cfg))
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
def hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, h, A, b, c, K, ytmp, ynew, g0, g1, ftmp):
    """Advance (t, y) by h with event-driven mode switching.

    On entry k1/fric hold the derivative and friction torques at (t, y) with the
    current modes and input u; on exit they hold them at the new state (so the
    next step reuses them).  Returns the number of mode switches.
    """
    remaining = h
    n_events = 0
    n = y.shape[0]
    kend = K[K.shape[0] - 1]
    fend0 = 0.0
    fend1 = 0.0
    while True:
        _rk_step(t, y, k1, mode, u, p, cfg, eps, remaining, A, b, c, K, ytmp, ynew, ftmp)
        state_derivative(t + remaining, ynew, mode, u, p, cfg, eps, kend, ftmp)
        fend0 = ftmp[0]
        fend1 = ftmp[1]
        if eps > 0.0 or n_events >= MAX_EVENTS_PER_STEP:
            break
        event_values(t + remaining, ynew, mode, ftmp, p, cfg, g1)
        if g1[0] >= 0.0 and g1[1] >= 0.0:
            break
        event_values(t, y, mode, fric, p, cfg, g0)
        # earliest crossing by linear estimate
        j = -1
        tau_best = 2.0
        for q in range(2):
            if g1[q] < 0.0:
                tau = g0[q] / (g0[q] - g1[q]) if g0[q] > 0.0 else 0.0
                if tau < tau_best:
                    tau_best = tau
                    j = q
        # Illinois refinement of the crossing of g_j on [0, 1] (fraction of `remaining`)
        ta = 0.0
        ga = g0[j]
        tb = 1.0
        gb = g1[j]
        tau = tau_best
        side = 0
        if ga > 0.0:
            for _ in range(ILLINOIS_ITERATIONS):
                _rk_step(t, y, k1, mode, u, p, cfg, eps, tau * remaining, A, b, c, K, ytmp, ynew, ftmp)
                state_derivative(t + tau * remaining, ynew, mode, u, p, cfg, eps, ytmp, ftmp)
                event_values(t + tau * remaining, ynew, mode, ftmp, p, cfg, g1)
                gt = g1[j]
                if gt == 0.0:
                    tb = tau
                    break
                if gt > 0.0:
                    ta = tau
                    ga = gt
                    if side == 1:
                        gb *= 0.5
                    side = 1
                else:
                    tb = tau
                    gb = gt
                    if side == -1:
                        ga *= 0.5
                    side = -1
                tau = (ta * gb - tb * ga) / (gb - ga)
            tau = tb  # end just after the crossing
        else:
            tau = 0.0
        # advance to the event
        if tau > 0.0:
            _rk_step(t, y, k1, mode, u, p, cfg, eps, tau * remaining, A, b, c, K, ytmp, ynew, ftmp)
            for i in range(n):
                y[i] = ynew[i]
        t += tau * remaining
        remaining -= tau * remaining
        # switch the mode of disc j
        if mode[j] != 0:
            if j == 0:
                y[S_WU] = 0.0
            else:
                y[S_WL] = 0.0
            mode[j] = 0
        else:
            state_derivative(t, y, mode, u, p, cfg, 0.0, k1, fric)
            if j == 0:
                lo, hi = upper_stick_bounds(p)
            else:
                lo, hi = lower_stick_bounds(y[S_TL], t, p, brake_on(cfg))
            mode[j] = 1 if (fric[j] - lo) >= (hi - fric[j]) else -1
        resolve_modes(t, y, mode, u, p, cfg, k1, fric)
        n_events += 1
        if remaining <= 1e-15:
            return n_events
    for i in range(n):
        y[i] = ynew[i]
        k1[i] = kend[i]
    fric[0] = fend0
    fric[1] = fend1
    return n_events


@njit(cache=True, _nrt=False)
def record(out, row, t, u, y, fric, mode):
    """Write one output sample (columns OUTPUT_NAMES)."""
    out[row, 0] = t
    out[row, 1] = u
    for i in range(N_STATE):
        out[row, 2 + i] = y[i]
    ct = np.cos(y[S_TU])
    st = np.sin(y[S_TU])
    X = y[S_X] * ct - y[S_Y] * st
    Y = y[S_X] * st + y[S_Y] * ct
    out[row, 11] = y[S_TL] - y[S_TU]
    out[row, 12] = X
    out[row, 13] = Y
    out[row, 14] = np.sqrt(X * X + Y * Y)
    out[row, 15] = fric[0]
    out[row, 16] = fric[1]
    out[row, 17] = 1.0 if mode[0] == 0 else 0.0
    out[row, 18] = 1.0 if mode[1] == 0 else 0.0


@njit(cache=True)
def run_trajectory(y, mode, U, p, cfg, dt, t0, eps, A, b, c, rec_every, out, init_modes):
    """Integrate one trajectory over len(U) steps (input U[i] held over step i).

    ``y``/``mode`` are updated in place to the final state.  ``out`` receives
    ``len(U) // rec_every + 1`` samples.  Returns the number of mode switches.
    """
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    t = t0
    u = U[0] if U.shape[0] > 0 else 0.0
    if eps > 0.0:  # smoothed friction: no stick state
        mode[0] = 2
        mode[1] = 2
        state_derivative(t, y, mode, u, p, cfg, eps, k1, fric)
    elif init_modes:
        initial_modes(t, y, u, p, cfg, mode, k1, fric)
    else:
        resolve_modes(t, y, mode, u, p, cfg, k1, fric)
    record(out, 0, t, u, y, fric, mode)
    n_switch = 0
    row = 1
    u_prev = u
    for i in range(U.shape[0]):
        u = U[i]
        if u != u_prev:
            if eps > 0.0:
                state_derivative(t, y, mode, u, p, cfg, eps, k1, fric)
            else:
                resolve_modes(t, y, mode, u, p, cfg, k1, fric)
            u_prev = u
        n_switch += hybrid_step(t, y, k1, fric, mode, u, p, cfg, eps, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
        t = t0 + (i + 1) * dt
        if (i + 1) % rec_every == 0:
            # a sample carries the voltage applied from its time on (zero-order hold), as a recording does
            u_next = U[i + 1] if i + 1 < U.shape[0] else u
            record(out, row, t, u_next, y, fric, mode)
            row += 1
    return n_switch


@njit(cache=True)
def run_batch_serial(Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes):
    """run_trajectory over a batch: Y (B, N_STATE), MODE (B, 2), U (B, n), P (B, n_par), OUT (B, n_rec, N_OUT)."""
    for k in range(Y.shape[0]):
        run_trajectory(Y[k], MODE[k], U[k], P[k], cfg, dt, T0[k], eps, A, b, c, rec_every, OUT[k], init_modes)


@njit(cache=True, parallel=True)
def run_batch_parallel(Y, MODE, U, P, cfg, dt, T0, eps, A, b, c, rec_every, OUT, init_modes):
    """As run_batch_serial, trajectories spread over numba's threads."""
    for k in prange(Y.shape[0]):
        run_trajectory(Y[k], MODE[k], U[k], P[k], cfg, dt, T0[k], eps, A, b, c, rec_every, OUT[k], init_modes)


@njit(cache=True)
def advance_batch(Y, MODE, u, P, cfg, dt, n_sub, T, eps, A, b, c, FRIC):
    """Advance every trajectory of a batch by n_sub steps of dt at constant input u[k]
    (the environments' control period).  Updates Y, MODE, T in place; FRIC (B, 2)
    receives the friction torques at the end."""
    K, ytmp, k1, ynew, _, ftmp, g0, g1 = alloc_work(b.shape[0])
    for k in range(Y.shape[0]):
        y = Y[k]
        mode = MODE[k]
        fric = FRIC[k]
        t = T[k]
        if eps > 0.0:
            mode[0] = 2
            mode[1] = 2
            state_derivative(t, y, mode, u[k], P[k], cfg, eps, k1, fric)
        else:
            resolve_modes(t, y, mode, u[k], P[k], cfg, k1, fric)
        for _ in range(n_sub):
            hybrid_step(t, y, k1, fric, mode, u[k], P[k], cfg, eps, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
            t += dt
        T[k] = t
