"""The PI speed loop of :class:`controllers.pi.PIController` as a compiled law.

State rows (per lane): the last motor angle (rad), the speed estimate (rad/s), the integral of the speed
error (rad), the feedforward voltage (V) and the target (rad/s); constants: the low-pass coefficient, the
period (s), the gains kp (V s/rad), ki (V/rad) and the voltage limit (V).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.closed_loop.abi import LAW_SIGNATURE, M_TU

__all__ = ["pi_step", "pi_state", "pi_constants"]

PREV, OMEGA, INTEGRAL, U_FF, REF = range(5)
A, DT, KP, KI, U_MAX = range(5)


@njit(inline="always")
def _sign(x):
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


@njit(LAW_SIGNATURE, cache=True)
def pi_step(t, M, X, C, U):  # pragma: no cover - compiled
    """One period of the PI loop of every lane (:class:`controllers.pi.MotorSpeedPI`, the encoder speed of
    :class:`drillgym.measurement.EncoderVelocityEstimator`)."""
    a, dt, kp, ki, u_max = C[A], C[DT], C[KP], C[KI], C[U_MAX]
    for k in range(U.size):
        theta = M[M_TU, k]
        w = a * X[OMEGA, k] + (1.0 - a) * ((theta - X[PREV, k]) / dt)
        X[OMEGA, k] = w
        X[PREV, k] = theta
        e = X[REF, k] - w
        u = X[U_FF, k] + kp * e + ki * X[INTEGRAL, k]
        if not (abs(u) >= u_max and _sign(e) == _sign(u)):
            X[INTEGRAL, k] = X[INTEGRAL, k] + e * dt
        U[k] = min(max(X[U_FF, k] + kp * e + ki * X[INTEGRAL, k], -u_max), u_max)


def pi_state(prev, omega, integral, u_ff, ref) -> np.ndarray:
    """The law's state (5, n) from the controller's (rad, rad/s, rad, V, rad/s)."""
    return np.ascontiguousarray(np.stack([prev, omega, integral, u_ff, ref]), dtype=np.float64)


def pi_constants(a: float, dt: float, kp: float, ki: float, u_max: float) -> np.ndarray:
    """The law's constants (5,): low-pass coefficient, period (s), kp (V s/rad), ki (V/rad), limit (V)."""
    return np.array([a, dt, kp, ki, u_max], dtype=np.float64)
