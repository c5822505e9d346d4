"""Compiled observation pipelines of the 'sensors' and 'motor' modes: one call per control period.

For every rig (row) one call quantizes the encoders, updates the speed estimators, reads the
LVDTs (noise from the rig's pre-drawn block), assembles the observation vector and clips it into
the Box, without Python-level work per quantity; :mod:`.observation` calls these kernels from its
classes.  The formulas are the elementwise functions of :mod:`drillgym.measurement`
(``encoder_reading``, ``filtered_speed``) and :func:`rotate` / :func:`wrap_angle` below, compiled
here by numba and used as they are by the numpy paths: one formula per quantity.  The simulated
readings (true state -> Measurement effects of the composition -> encoders, LVDT noise) are the
client template :mod:`.sensor_kernel`, specialised per composition of effects; this module
assembles observations from readings (the hardware twin and the agents use it directly).

Argument conventions (all kernels are batched over the rows of ``out``):

* ``E`` estimator states, float64 (2 per encoder, n): rows ``prev, omega`` of the motor encoder,
  then (sensors mode) of the lower-disc encoder; ``EncoderVelocityEstimator.prev`` / ``.omega``
  of the observation classes are views of these rows.
* ``cv`` constants, float64: the ``SC_*`` (sensors) or ``MC_*`` (motor) layout, then the
  observation bounds ``low`` (dim) and ``high`` (dim).
* ``out`` (n, dim) float32, written in place; values are clipped into [low, high].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..measurement import encoder_reading, filtered_speed

__all__ = [
    "MM",
    "rotate",
    "wrap_angle",
    "rotate_compiled",
    "encoder_compiled",
    "sensor_constants",
    "motor_constants",
    "sensor_row",
    "sensors_rows",
    "motor_row",
    "motor_rows",
]

MM = 1e3  # m -> mm

# layout of the sensors constants: lateral (0/1), counts per rev, filter coefficient a, control period (s),
# LVDT noise std (m, 0: none), then the bounds (offsets, skew ... are Measurement effects of the composition)
SC_LATERAL, SC_CPR, SC_A, SC_DT, SC_NOISE, SC_BOUNDS = range(6)
# layout of the motor constants: counts per rev, filter coefficient a, control period (s), then the bounds
MC_CPR, MC_A, MC_DT, MC_BOUNDS = range(4)


def rotate(x, y, c, s):
    """Components in the fixed frame of the vector (x, y) given in a frame rotated by an angle of
    cosine ``c`` and sine ``s`` (arrays or floats)."""
    return x * c - y * s, x * s + y * c


def wrap_angle(theta):
    """Angle (rad) wrapped to [-pi, pi) (arrays or floats)."""
    return np.mod(theta + np.pi, 2 * np.pi) - np.pi


rotate_compiled = njit(cache=True)(rotate)
_wrap = njit(cache=True)(wrap_angle)
encoder_compiled = njit(cache=True)(encoder_reading)
_speed = njit(cache=True)(filtered_speed)


def sensor_constants(
    lateral: bool, counts_per_rev: int, a: float, dt: float, noise_std: float, low: np.ndarray, high: np.ndarray
) -> np.ndarray:
    """The ``cv`` vector of the sensors kernels (SC_* layout; noise in m, dt in s)."""
    head = [float(lateral), counts_per_rev, a, dt, noise_std]
    return np.concatenate([np.asarray(head, dtype=float), low, high]).astype(float)


def motor_constants(counts_per_rev: int, a: float, dt: float, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The ``cv`` vector of the motor kernels (MC_* layout)."""
    return np.concatenate([np.asarray([counts_per_rev, a, dt], dtype=float), low, high]).astype(float)


@njit(cache=True)
def _put(out, k, i, value, cv, bounds):
    """out[k, i] = value clipped into [low_i, high_i] (bounds from cv[bounds:]); NaN stays NaN as with np.clip."""
    dim = out.shape[1]
    lo = cv[bounds + i]
    hi = cv[bounds + dim + i]
    if value < lo:
        value = lo
    elif value > hi:
        value = hi
    out[k, i] = value


@njit(cache=True)
def _estimate(E, r, k, theta, a, dt):
    """Speed estimate (rad/s) of encoder ``r`` of rig ``k`` after the angle ``theta`` (rad); updates E."""
    w = _speed(E[2 * r + 1, k], theta, E[2 * r, k], a, dt)
    E[2 * r, k] = theta
    E[2 * r + 1, k] = w
    return w


@njit(cache=True)
def sensor_row(k, theta_u, theta_l, xm, ym, u_prev, omega_ref, E, cv, update, out):
    """Row k of the 'sensors' observation from one period's readings (rad, m, V, rad/s).
    ``update``: advance the speed estimators; otherwise (reset observation) speeds are 0."""
    if update:
        omega_u = _estimate(E, 0, k, theta_u, cv[SC_A], cv[SC_DT])
        omega_l = _estimate(E, 1, k, theta_l, cv[SC_A], cv[SC_DT])
    else:
        omega_u = 0.0
        omega_l = 0.0
    b = SC_BOUNDS
    _put(out, k, 0, _wrap(theta_u), cv, b)
    _put(out, k, 1, _wrap(theta_l), cv, b)
    _put(out, k, 2, theta_l - theta_u, cv, b)
    _put(out, k, 3, omega_u, cv, b)
    _put(out, k, 4, omega_l, cv, b)
    j = 5
    if cv[SC_LATERAL] > 0.0:
        _put(out, k, 5, MM * xm, cv, b)
        _put(out, k, 6, MM * ym, cv, b)
        j = 7
    _put(out, k, j, u_prev, cv, b)
    _put(out, k, j + 1, omega_ref, cv, b)


@njit(cache=True)
def sensors_rows(theta_u, theta_l, X, Y, u_prev, omega_ref, E, cv, update, out):
    """'sensors' observations of all rows from readings: encoder angles (rad), LVDT readings X, Y (m;
    any array when not lateral), voltages (V), targets (rad/s).  ``update`` as in ``sensor_row``."""
    lateral = cv[SC_LATERAL] > 0.0
    for k in range(out.shape[0]):
        xm = X[k] if lateral else 0.0
        ym = Y[k] if lateral else 0.0
        sensor_row(k, theta_u[k], theta_l[k], xm, ym, u_prev[k], omega_ref[k], E, cv, update, out)


@njit(cache=True)
def motor_row(k, theta_u, u_prev, omega_ref, E, hist, cv, update, out):
    """Row k of the 'motor' observation: shift the history ``hist`` (n, 2H: increments, voltages;
    newest first) by one period and add the increment of ``theta_u`` (rad) / dt and ``u_prev`` (V).
    Without ``update`` (reset observation): an empty history, ``hist`` untouched."""
    H = hist.shape[1] // 2
    b = MC_BOUNDS
    if update:
        for i in range(H - 1, 0, -1):
            hist[k, i] = hist[k, i - 1]
            hist[k, H + i] = hist[k, H + i - 1]
        hist[k, 0] = _estimate(E, 0, k, theta_u, cv[MC_A], cv[MC_DT])
        hist[k, H] = u_prev
        for i in range(2 * H):
            _put(out, k, i, hist[k, i], cv, b)
    else:
        for i in range(2 * H):
            _put(out, k, i, 0.0, cv, b)
    _put(out, k, 2 * H, omega_ref, cv, b)


@njit(cache=True)
def motor_rows(theta_u, u_prev, omega_ref, E, hist, cv, update, out):
    """'motor' observations of all rows from the motor encoder angles (rad), voltages (V), targets (rad/s)."""
    for k in range(out.shape[0]):
        motor_row(k, theta_u[k], u_prev[k], omega_ref[k], E, hist, cv, update, out)
