"""Reward of the speed-tracking task (hold the lower disc at omega_ref without stick-slip).

Per control period, with u the (clipped) voltage applied over it and u_prev the one before::

    r = -( w_track  * |omega_l - omega_ref| / omega_ref
         + w_stick  * [lower disc stuck at the end of the period]
         + w_effort * (u / 5 V)^2
         + w_rate   * ((u - u_prev) / 5 V)^2 )

Defaults (``RewardWeights``): w_track = 1, w_stick = 0.5, w_effort = 0.01, w_rate = 0.05,
so r lies in about [-2.6, 0]; r = 0 only at perfect tracking with no effort.
The tracking error is relative, so episodes with different targets weigh alike;
a stuck disc costs w_track + w_stick = 1.5 per period.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .options import U_MAX, RewardWeights

__all__ = ["TrackingReward", "reward_value"]


@njit(cache=True)
def reward_value(omega_l, omega_ref, stuck, u, u_prev, w):
    """Reward of one period (compiled; ``w`` = [track, stick, effort, rate] weights)."""
    e = abs(omega_l - omega_ref) / omega_ref
    du = (u - u_prev) / U_MAX
    un = u / U_MAX
    return -(w[0] * e + w[1] * (1.0 if stuck else 0.0) + w[2] * un * un + w[3] * du * du)


@njit(cache=True)
def _reward_kernel(Y, MODE, u, u_prev, omega_ref, w, out):
    for k in range(Y.shape[0]):
        out[k] = reward_value(Y[k, 3], omega_ref[k], MODE[k, 1] == 0, u[k], u_prev[k], w)


class TrackingReward:
    """Batched reward of the tracking task (formula in the module docstring).

    Parameters
    ----------
    weights : RewardWeights
        Weights of the reward terms.
    """

    def __init__(self, weights: RewardWeights) -> None:
        self.weights = weights
        self.w = np.array([weights.track, weights.stick, weights.effort, weights.rate])

    def __call__(
        self, Y: np.ndarray, MODE: np.ndarray, u: np.ndarray, u_prev: np.ndarray, omega_ref: np.ndarray, out: np.ndarray
    ) -> None:
        """Write the rewards of all rigs into ``out`` (n,): states ``Y`` (n, n_state), friction modes
        ``MODE`` (n, 2), voltages ``u``, ``u_prev`` (V), targets ``omega_ref`` (rad/s)."""
        _reward_kernel(Y, MODE, u, u_prev, omega_ref, self.w, out)
