"""The task: target speed per episode, initial winding, safety limits, episode length,
and the running stick-slip severity reported in ``info``.

The per-rig rules are compiled functions (``unsafe_row``, ``ssi_push``) so the engine's
period kernel applies them without leaving compiled code; the classes wrap them for
batched use on their own.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .options import EnvOptions

__all__ = ["SpeedTrackingTask", "StickSlipMonitor", "unsafe_row", "ssi_push"]


@njit(cache=True)
def unsafe_row(y, max_speed, max_lateral, lateral):
    """True when state ``y`` breaks a safety limit (over-speed, lateral displacement)."""
    bad = abs(y[2]) > max_speed or abs(y[3]) > max_speed
    if lateral:
        bad = bad or (y[4] * y[4] + y[5] * y[5]) > max_lateral * max_lateral
    return bad


@njit(cache=True)
def _limits_kernel(Y, max_speed, max_lateral, lateral, out):
    for k in range(Y.shape[0]):
        out[k] = unsafe_row(Y[k], max_speed, max_lateral, lateral)


class SpeedTrackingTask:
    """Hold the lower disc at omega_ref (rad/s) without stick-slip.

    Per episode: ``omega_ref`` fixed or uniform in ``omega_ref_range``; initial winding
    alpha0 uniform in ``alpha0_range`` (rad), rigs start at rest.  Terminated when
    |omega_u| or |omega_l| > ``max_speed`` (rad/s) or, with lateral motion, r > ``max_lateral``
    (m); truncated after ``episode_duration`` (s).
    """

    def __init__(self, options: EnvOptions) -> None:
        self.o = options
        self.max_steps = options.episode_steps
        self.max_speed = float(options.max_speed)
        self.max_lateral = float(options.max_lateral)
        self.lateral = bool(options.lateral)

    def sample(self, rng: np.random.Generator) -> tuple[float, float]:
        """(omega_ref, alpha0) for a new episode, drawn from ``rng`` in that order."""
        o = self.o
        w = float(o.omega_ref) if o.omega_ref is not None else float(rng.uniform(*o.omega_ref_range))
        a = float(rng.uniform(*o.alpha0_range))
        return w, a

    def unsafe(self, Y: np.ndarray, out: np.ndarray) -> None:
        """Write the termination flags (safety limits) of states ``Y`` (n, n_state) into ``out`` (n,) bool."""
        _limits_kernel(Y, self.max_speed, self.max_lateral, self.lateral, out)


@njit(cache=True)
def ssi_push(w, bmax, bmin, bsum, counts, block_len):
    """Add sample ``w`` (rad/s) to one rig's block window and return its SSI.

    bmax, bmin, bsum: (n_blocks,) block statistics; counts: (n_blocks + 2,) int, the block
    sample counts followed by [current block, position in it]."""
    nb = bmax.shape[0]
    j = counts[nb]
    bmax[j] = max(bmax[j], w)
    bmin[j] = min(bmin[j], w)
    bsum[j] += w
    counts[j] += 1
    mx = -np.inf
    mn = np.inf
    s = 0.0
    c = 0
    for i in range(nb):
        if counts[i] > 0:
            mx = max(mx, bmax[i])
            mn = min(mn, bmin[i])
            s += bsum[i]
            c += counts[i]
    mean = abs(s / c)
    span = mx - mn
    ssi = span / (2.0 * max(mean, 1e-3)) if span > 1e-9 else 0.0
    counts[nb + 1] += 1
    if counts[nb + 1] >= block_len:  # start a new block, dropping the oldest
        counts[nb + 1] = 0
        j = (j + 1) % nb
        counts[nb] = j
        bmax[j] = -np.inf
        bmin[j] = np.inf
        bsum[j] = 0.0
        counts[j] = 0
    return ssi


@njit(cache=True)
def _ssi_kernel(omega_l, W, C, block_len, out):
    for k in range(omega_l.shape[0]):
        out[k] = ssi_push(omega_l[k], W[k, 0], W[k, 1], W[k, 2], C[k], block_len)


class StickSlipMonitor:
    """Running stick-slip severity SSI = (max omega_l - min omega_l) / (2 |mean omega_l|) over the
    last ``window`` seconds (0: steady rotation or rest; about 1 or more: stick-slip).

    The window is kept as ``n_blocks`` blocks of max/min/sum (O(n_blocks) per step), so it
    spans between (n_blocks - 1)/n_blocks and 1 window.  |mean| is floored at 1e-3 rad/s.
    Arrays: ``W`` (n, 3, n_blocks) block max/min/sum, ``C`` (n, n_blocks + 2) block counts,
    current block, position in it."""

    def __init__(self, n: int, window: float, control_dt: float, n_blocks: int = 10) -> None:
        steps = max(1, int(round(window / control_dt)))
        n_blocks = min(n_blocks, steps)
        self.block_len = max(1, steps // n_blocks)
        self.W = np.zeros((n, 3, n_blocks))
        self.C = np.zeros((n, n_blocks + 2), dtype=np.int64)
        self.ssi = np.zeros(n)
        self.reset(np.arange(n))

    def reset(self, index: np.ndarray) -> None:
        self.W[index, 0] = -np.inf
        self.W[index, 1] = np.inf
        self.W[index, 2] = 0.0
        self.C[index] = 0
        self.ssi[index] = 0.0

    def update(self, omega_l: np.ndarray) -> np.ndarray:
        """Add one sample per rig (rad/s); returns the severities (n,)."""
        _ssi_kernel(omega_l, self.W, self.C, self.block_len, self.ssi)
        return self.ssi
