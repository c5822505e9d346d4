"""The diagnosis' effective sample count per block and the spread its candidate fits start from."""

import numpy as np
import pytest

from drillgym.diagnosis.effective import MIN_EFFECTIVE, effective_samples
from drillgym.diagnosis.effects import get_effect
from drillgym.diagnosis.starts import search_points


def _ar1(n: int, rho: float, rng: np.random.Generator) -> np.ndarray:
    e = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = e[0]
    for i in range(1, n):
        x[i] = rho * x[i - 1] + np.sqrt(1 - rho**2) * e[i]
    return x


def test_white_noise_counts_every_sample_and_ar1_its_textbook_share():
    rng = np.random.default_rng(0)
    assert effective_samples(rng.standard_normal(4000)) == pytest.approx(4000, rel=0.1)
    assert effective_samples(_ar1(20000, 0.8, rng)) == pytest.approx(20000 * 0.2 / 1.8, rel=0.15)


def test_each_block_of_a_smooth_residual_counts_at_least_once():
    """A residual smooth over the whole record (a slow sine cut into 30 segments) counts 30, not the floor."""
    n_blocks, L = 30, 200
    r = np.sin(2 * np.pi * np.arange(n_blocks * L) / (n_blocks * L))
    blocks = np.repeat(np.arange(n_blocks), L)
    assert effective_samples(r) == MIN_EFFECTIVE
    assert effective_samples(r, blocks) == pytest.approx(n_blocks, abs=1.0)


def test_search_points_start_at_the_guess_stay_in_bounds_and_spread_over_scales():
    delay = get_effect("input_delay")
    pts = search_points(delay)
    p = delay.parameters[0]
    assert pts.shape[1] == 1 and pts[0, 0] == p.guess
    assert np.all((pts >= p.lo) & (pts <= p.hi))
    assert pts.max() >= p.guess + 3 * p.scale  # reaches a 37 ms delay from the 5 ms guess
    assert len(np.unique(pts)) == len(pts)
    pf = get_effect("position_friction")
    rows = search_points(pf)
    assert rows.shape == (9, 4) and np.all(rows[0] == [q.guess for q in pf.parameters])
    assert np.all(np.ptp(rows, axis=0) > 2 * np.array([q.scale for q in pf.parameters]))
    assert np.array_equal(rows, search_points(pf))  # deterministic
