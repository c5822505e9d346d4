"""Client kernel template: the simulated sensors of the 'sensors' and 'motor' observations.

Per rig and control period, ONE compiled call reads the true state, applies the composition's
Measurement effects (``hk_measure``: offsets, skew, gains, any user effect) to the channels
theta_u, theta_l (rad) and the fixed-frame lateral position X, Y (m), then quantizes the encoders,
adds the LVDT noise and assembles the observation (:mod:`.observation_kernels`).  Specialised
per composition of effects (:meth:`drillgym.effects.codegen.CompiledModel.client`), so the
environments measure exactly as :func:`drillgym.measurement.measure_trajectory` and the rig
emulator do.  ``P`` is the (n, n_params) parameter matrix of the rigs (the composition's layout).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drillgym.envs.observation_kernels import (
    MC_CPR,
    SC_CPR,
    SC_LATERAL,
    SC_NOISE,
    encoder_compiled,
    motor_row,
    rotate_compiled,
    sensor_row,
)
from drillgym.kernels.hooks import hk_measure

__all__ = ["measured_channels", "measured_channels_batch", "sensors_observe", "motor_observe"]


@njit(cache=True)
def measured_channels(y, p):
    """(theta_u, theta_l, X, Y) of state ``y`` as the sensors read them before quantization and noise
    (rad, rad, m, m).  A disc held at the centre (torsional) skips the frame rotation: X = Y = 0."""
    X = 0.0
    Yf = 0.0
    if y[4] != 0.0 or y[5] != 0.0:
        X, Yf = rotate_compiled(y[4], y[5], np.cos(y[0]), np.sin(y[0]))
    return hk_measure(y[0], y[1], X, Yf, y[2], y[3], p)


@njit(cache=True)
def measured_channels_batch(Y, P):
    """(4, n) measured channels theta_u, theta_l, X, Y of the states Y (n, n_state), rows of P."""
    out = np.empty((4, Y.shape[0]))
    for k in range(Y.shape[0]):
        a, b, c, d = measured_channels(Y[k], P[k])
        out[0, k] = a
        out[1, k] = b
        out[2, k] = c
        out[3, k] = d
    return out


@njit(cache=True)
def sensors_observe(Y, P, u_prev, omega_ref, E, noise, pos, cv, out):
    """'sensors' observations of simulated states ``Y`` after one period: measured channels,
    quantized encoders, speed estimators, LVDTs with noise ``noise[k, pos[k]]`` (standard normal,
    scaled by cv[SC_NOISE]; ``pos`` advanced).  Returns the number of rows whose noise block is used
    up (``pos[k] == noise.shape[1]``): the caller refills them (or resets pos) before the next call."""
    lateral = cv[SC_LATERAL] > 0.0
    cpr = cv[SC_CPR]
    std = cv[SC_NOISE]
    spent = 0
    for k in range(Y.shape[0]):
        tu, tl, xm, ym = measured_channels(Y[k], P[k])
        theta_u = encoder_compiled(tu, cpr)
        theta_l = encoder_compiled(tl, cpr)
        if lateral:
            if std > 0.0:
                p = pos[k]
                xm += std * noise[k, p, 0]
                ym += std * noise[k, p, 1]
                pos[k] = p + 1
                if p + 1 >= noise.shape[1]:
                    spent += 1
        else:
            xm = 0.0
            ym = 0.0
        sensor_row(k, theta_u, theta_l, xm, ym, u_prev[k], omega_ref[k], E, cv, True, out)
    return spent


@njit(cache=True)
def motor_observe(Y, P, u_prev, omega_ref, E, hist, cv, out):
    """'motor' observations of simulated states ``Y``: the motor encoder quantizes the measured theta_u."""
    cpr = cv[MC_CPR]
    for k in range(Y.shape[0]):
        tu = measured_channels(Y[k], P[k])[0]
        motor_row(k, encoder_compiled(tu, cpr), u_prev[k], omega_ref[k], E, hist, cv, True, out)
