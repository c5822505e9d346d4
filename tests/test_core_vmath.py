"""The vectorisable power: what ``**`` gives, and a loop of it vectorises; effect functions' lane variants use it."""

import textwrap

import numpy as np
import pytest
from numba import njit

from drillgym.effects.simd import simd_variant
from drillgym.vmath import vpow


@njit(error_model="numpy")  # as the kernels: a division raises no exception, so loops vectorise
def _powers(a, b, out):
    for i in range(a.size):
        out[i] = vpow(a[i], b[i])


def test_vpow_gives_what_the_power_operator_gives():
    rng = np.random.default_rng(0)
    a, b = np.exp(rng.uniform(-30.0, 30.0, 20_000)), rng.uniform(-6.0, 6.0, 20_000)
    out = np.empty_like(a)
    _powers(a, b, out)
    scale = 1.0 + np.abs(b * np.log(a))
    assert np.max(np.abs(out / a**b - 1.0) / scale) < 1e-15
    special = [(0.0, 2.5), (0.0, 0.0), (-2.0, 3.0), (-2.0, 2.0), (0.0, -1.0), (7.0, 0.0), (-3.0, -1.0)]
    a, b = (np.array(c) for c in zip(*special, strict=True))
    _powers(a, b, out := np.empty(a.size))
    with np.errstate(divide="ignore"):
        np.testing.assert_allclose(out, a**b, rtol=1e-15)
    _powers(np.array([-2.0]), np.array([0.5]), out := np.empty(1))
    assert np.isnan(out[0])  # a negative base and a fractional exponent, as **


def test_a_loop_of_vpow_vectorises():
    _powers(np.ones(4), np.ones(4), np.empty(4))  # compiled in this process (the tests may run apart)
    ir = next(iter(_powers.inspect_llvm().values()))
    assert "x double>" in ir and "@pow" not in ir


def test_an_effect_functions_lane_variant_replaces_its_fractional_powers(tmp_path):
    path = tmp_path / "shape.py"
    path.write_text(
        textwrap.dedent(
            """
            import math

            def slip(speed, ws, delta):
                return math.exp(-(speed / ws) ** delta) + speed ** 2 + abs(speed) ** 0.5
            """
        )
    )
    ns: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), ns)
    plain = ns["slip"]
    lane = simd_variant(plain)
    assert lane is not plain and lane.__globals__["_drillgym_vpow"] is vpow
    compiled = njit(lane)
    for speed in (0.0, 0.03, 0.7, 4.0):
        assert compiled(speed, 0.1, 1.3) == pytest.approx(plain(speed, 0.1, 1.3), rel=1e-14)


def test_a_function_without_fractional_powers_is_kept():
    def square(x):
        return x**2

    assert simd_variant(square) is square
