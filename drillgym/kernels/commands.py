"""Kernel template: what the motor sees: command tables and the transport-delay line (scalar path).

Transport delay (a Delay effect): every trajectory carries a delay line ``hist`` of the
commanded voltages of its last steps and ``head`` (index of the newest; -1 = empty: the
first command fills it, i.e. before the run the command was held at its first value).  At
step i the motor sees u(t_i - d), linear between the per-step commands (as
``numpy.interp`` of the zero-order-hold sequence).

This template is specialised per composition of effects (:mod:`drillgym.effects.codegen`); the
delay comes from the composition's hooks.
"""

from __future__ import annotations

from numba import njit

from drillgym.kernels.hooks import HAS_DELAY, hk_delay

__all__ = ["command_at", "delay_line_read", "delay_line_step"]


@njit(inline="always")
def command_at(U, i, USTEP, j):
    """(command of grid step i (V), table cursor).  Without a table (USTEP None) U holds one value per
    step or one value for all; with one, U[j] applies from step USTEP[j] on (a piecewise-constant
    (t, u) table evaluated here, never expanded per step) and j is the cursor (i non-decreasing)."""
    if USTEP is None:
        return (U[i] if U.shape[0] > 1 else U[0]), j
    m = USTEP.shape[0]
    while j + 1 < m and USTEP[j + 1] <= i:
        j += 1
    return U[j], j


@njit(cache=True, _nrt=False)
def delay_line_step(hist, head, u, p, dt):
    """Push the command u (V) of a new step into the delay line and return what the motor sees
    (u itself without a Delay effect)."""
    if not HAS_DELAY:
        return u
    L = hist.shape[0]
    h = head[0]
    if h < 0:
        for i in range(L):
            hist[i] = u
        h = 0
    else:
        h += 1
        if h >= L:
            h = 0
        hist[h] = u
    head[0] = h
    return delay_line_read(hist, head, u, p, dt)


@njit(cache=True, _nrt=False)
def delay_line_read(hist, head, u, p, dt):
    """What the motor sees now (without pushing a new command); u when the line is empty."""
    if not HAS_DELAY:
        return u
    h = head[0]
    if h < 0:
        return u
    L = hist.shape[0]
    m = max(hk_delay(p), 0.0) / dt
    n = int(m)
    f = m - n
    if n > L - 2:  # the caller sizes the line; never read past it
        n = L - 2
        f = 1.0
    i0 = h - n
    if i0 < 0:
        i0 += L
    i1 = i0 - 1
    if i1 < 0:
        i1 += L
    return (1.0 - f) * hist[i0] + f * hist[i1]
