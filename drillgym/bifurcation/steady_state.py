"""Steady-state statistics of a run (simulated or measured): the quantities of a bifurcation diagram."""

from __future__ import annotations

import numpy as np

STAT_NAMES = ("omega_l_min", "omega_l_max", "r_min", "r_max", "period", "stick_fraction")
OSCILLATION_MIN = 0.05  # rad/s: peak-to-peak omega_l below this counts as an equilibrium


def period_of(t: np.ndarray, w: np.ndarray) -> float:
    """Mean period (s) from the upward crossings of the mid-range level of w; NaN if < 2 crossings."""
    if w.max() - w.min() < OSCILLATION_MIN:
        return float("nan")
    level = 0.5 * (w.max() + w.min())
    up = np.flatnonzero((w[:-1] < level) & (w[1:] >= level))
    if len(up) < 2:
        return float("nan")
    tc = t[up] + (level - w[up]) / (w[up + 1] - w[up]) * (t[up + 1] - t[up])
    return float(np.mean(np.diff(tc)))


def stats_from_arrays(
    t: np.ndarray, omega_l: np.ndarray, r: np.ndarray | None = None, stick: np.ndarray | None = None
) -> np.ndarray:
    """(omega_l_min, omega_l_max, r_min, r_max, period, stick_fraction) of a steady-state window."""
    r = np.zeros_like(omega_l) if r is None else r
    sf = float(np.mean(stick)) if stick is not None else float(np.mean(np.abs(omega_l) < 1e-3))
    return np.array([omega_l.min(), omega_l.max(), r.min(), r.max(), period_of(t, omega_l), sf])


def steady_state_stats(traj, n_window: int, end: int | None = None) -> np.ndarray:
    """Statistics of a :class:`drillgym.Trajectory` over the ``n_window`` samples before ``end``."""
    end = traj.data.shape[0] if end is None else end
    sl = slice(max(0, end - n_window), end)
    return stats_from_arrays(traj.t[sl], traj.omega_l[sl], traj.r[sl], traj.stick_l[sl])
