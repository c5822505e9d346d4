"""The approach, descent and integral hold of :class:`controllers.descent.DescentController` as a compiled law.

State rows (per lane): the controller's clock (s, advanced by one period per call as ``_act`` advances it), the
target's equilibrium voltage (V), whether the lane descends (1) or holds its voltage from the start (0), the motor
angle when the integral began (rad), the integral of the commanded speed since then (rad), whether the integral
runs (1 once the hold is over); constants: the hold (s), the ramp (s), the integral gain (V/rad), the approach
voltage (V), the period (s), the equilibrium table's length m, then its voltages (V, m) and speeds (rad/s, m).
The loop clips the command to the amplifier's range, as ``act`` does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE, M_TU

__all__ = ["descent_step", "descent_state", "descent_constants"]

CLOCK, U_TARGET, DESCENDS, THETA0, REFERENCE_ANGLE, INTEGRATING = range(6)
HOLD, RAMP, KI, U_APPROACH, DT, N_TABLE = range(6)


@njit(LAW_SIGNATURE, cache=True)
def descent_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of every lane (:meth:`controllers.descent.DescentController._act`)."""
    hold, ramp, ki, u_app, dt = C[HOLD], C[RAMP], C[KI], C[U_APPROACH], C[DT]
    m = int(C[N_TABLE])
    u_grid = C[N_TABLE + 1 : N_TABLE + 1 + m]
    w_grid = C[N_TABLE + 1 + m : N_TABLE + 1 + 2 * m]
    for k in range(U.size):
        now = X[CLOCK, k]
        if ramp > 0:
            s = min(max((now - hold) / ramp, 0.0), 1.0)
        else:
            s = 1.0 if now >= hold else 0.0
        u = u_app + s * (X[U_TARGET, k] - u_app) if X[DESCENDS, k] != 0.0 else X[U_TARGET, k]
        if now >= hold:  # integral from the start of the descent on
            theta = M[M_TU, k]
            if X[INTEGRATING, k] == 0.0:
                X[INTEGRATING, k] = 1.0
                X[THETA0, k] = theta
            error = (theta - X[THETA0, k]) - X[REFERENCE_ANGLE, k]
            w_cmd = np.interp(u, u_grid, w_grid)  # the commanded speed of the feedforward, before the integral
            u = u - ki * error
            X[REFERENCE_ANGLE, k] = X[REFERENCE_ANGLE, k] + w_cmd * dt
        X[CLOCK, k] = now + dt
        U[k] = u


def descent_state(clock, u_target, descends, theta0, reference_angle, integrating) -> np.ndarray:
    """The law's state (6, n) from the controller's (s, V, bool, rad, rad, bool)."""
    n = np.size(u_target)
    rows = [np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in
            (clock, u_target, descends, theta0, reference_angle, integrating)]  # fmt: skip
    return np.ascontiguousarray(np.stack(rows), dtype=np.float64)


def descent_constants(hold, ramp, ki, u_approach, dt, u_grid, w_grid) -> np.ndarray:
    """The law's constants: hold (s), ramp (s), ki (V/rad), approach voltage (V), period (s), the equilibrium
    table's length and its voltages (V) and speeds (rad/s)."""
    head = [hold, ramp, ki, u_approach, dt, float(np.size(u_grid))]
    return np.ascontiguousarray(np.concatenate([head, np.ravel(u_grid), np.ravel(w_grid)]), dtype=np.float64)
