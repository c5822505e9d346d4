"""The compiled equations of motion against docs/model.md written out literally, and energy conservation."""

import math

import numpy as np
import pytest

from drillgym import RigParams, initial_state, simulate
from drillgym.configurations import Configuration
from drillgym.effects import BASE

state_derivative = BASE.kernels.model.state_derivative


def model_md_accelerations(state, u, p: RigParams, Tfu, Tfl):
    """Accelerations (x'', y'', theta_u'', theta_l'') from the four equations of docs/model.md, as printed there."""
    thu, thl, W, wl, x, y, xd, yd = state
    a = thl - thu
    ad = wl - W
    c, s = math.cos(a), math.sin(a)
    m, mr, e, Jl, Ju = p.m, p.mr, p.e, p.Jl, p.Ju
    b, k, kth, km = p.b, p.k, p.ktheta, p.km
    # rows x, y, alpha, theta_u; columns x'', y'', alpha'', theta_u''
    M = np.array(
        [
            [m, 0, -e * mr * s, -(e * mr * s + m * y)],
            [0, m, e * mr * c, e * mr * c + m * x],
            [-e * mr * s, e * mr * c, Jl, Jl + e * mr * (x * c + y * s)],
            [
                -(e * mr * s + m * y),
                e * mr * c + m * x,
                Jl + e * mr * (x * c + y * s),
                Ju + Jl + 2 * e * mr * (x * c + y * s) + m * (x * x + y * y),
            ],
        ]
    )
    rhs = -np.array(
        [
            b * (xd - y * W) + k * x - m * x * W**2 - 2 * m * W * yd - e * mr * c * (ad + W) ** 2,
            b * (yd + x * W) + k * y - m * y * W**2 + 2 * m * W * xd - e * mr * s * (ad + W) ** 2,
            2 * e * mr * W * (c * xd + s * yd) + e * mr * W**2 * (x * s - y * c) + kth * a + Tfl,
            b * ((x * x + y * y) * W + x * yd - y * xd)
            - e * mr * (x * s - y * c) * (ad**2 + 2 * ad * W)
            + 2 * e * mr * W * (c * xd + s * yd)
            + 2 * m * W * (x * xd + y * yd)
            + Tfu
            + Tfl
            - km * u,
        ]
    )
    xdd, ydd, add, thudd = np.linalg.solve(M, rhs)
    return np.array([xdd, ydd, thudd, add + thudd])


@pytest.mark.parametrize("seed", range(5))
def test_coupled_kernel_matches_model_md(seed):
    rng = np.random.default_rng(seed)
    p = RigParams()
    y = initial_state(
        alpha0=rng.uniform(-3, 3),
        theta_u0=rng.uniform(-5, 5),
        omega_u0=rng.uniform(0.5, 8),
        omega_l0=rng.uniform(0.5, 12),
        x0=rng.uniform(-4e-3, 4e-3),
        y0=rng.uniform(-4e-3, 4e-3),
        vx0=rng.uniform(-0.05, 0.05),
        vy0=rng.uniform(-0.05, 0.05),
    )
    mode = np.array([1, 1], dtype=np.int64)
    dy, fric = np.zeros(8), np.zeros(2)
    state_derivative(0.0, y, mode, 2.3, p.to_vector(), int(Configuration.COUPLED), 0.0, dy, fric)
    ref = model_md_accelerations(y, 2.3, p, fric[0], fric[1])
    np.testing.assert_allclose([dy[6], dy[7], dy[2], dy[3]], ref, rtol=1e-9, atol=1e-9)


def test_torsional_reduces_to_report_equations():
    """x = y = 0 held: Ju wu' + Tfu - ktheta alpha = km u and Jl wl' + Tfl + ktheta alpha = 0 (3.19), (3.20)."""
    p = RigParams()
    y = initial_state(alpha0=-0.7, omega_u0=2.0, omega_l0=3.0)
    mode = np.array([1, 1], dtype=np.int64)
    dy, fric = np.zeros(8), np.zeros(2)
    state_derivative(0.0, y, mode, 1.5, p.to_vector(), int(Configuration.TORSIONAL), 0.0, dy, fric)
    assert p.Ju * dy[2] + fric[0] - p.ktheta * (-0.7) == pytest.approx(p.km * 1.5, rel=1e-12)
    assert p.Jl * dy[3] + fric[1] + p.ktheta * (-0.7) == pytest.approx(0.0, abs=1e-12)


def coupled_energy(tr, p: RigParams):
    W, wl = tr.omega_u, tr.omega_l
    ad = wl - W
    x, y, xd, yd, a = tr.x_rot, tr.y_rot, tr.vx_rot, tr.vy_rot, tr.alpha
    c, s = np.cos(a), np.sin(a)
    Jc = p.Jl - p.mr * p.e**2
    vB2 = (xd - W * y) ** 2 + (yd + W * x) ** 2
    vC2 = (xd - p.e * s * ad - W * (y + p.e * s)) ** 2 + (yd + p.e * c * ad + W * (x + p.e * c)) ** 2
    T = 0.5 * p.Ju * W**2 + 0.5 * Jc * wl**2 + 0.5 * p.mr * vC2 + 0.5 * p.mt * vB2
    V = 0.5 * p.ktheta * a**2 + 0.5 * p.k * (x * x + y * y)
    return T + V


def test_energy_is_conserved_without_friction_and_damping():
    """Coupled, friction and damping zero, u = 0: relative energy drift < 1e-6 over 10 s (catches sign errors)."""
    p = RigParams().replace(Tcu=0.0, dTcu=0.0, bu=0.0, dbu=0.0, Ts=0.0, Tc=0.0, bb=0.0, b=0.0)
    x0 = initial_state(alpha0=0.4, omega_u0=1.2, omega_l0=2.5, x0=2e-3, y0=-1e-3, vx0=0.01)
    tr = simulate("coupled", 0.0, 10.0, params=p, x0=x0)
    E = coupled_energy(tr, p)
    assert np.ptp(tr.r) > 1e-3  # the disc really moves laterally
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-6


def test_energy_decays_with_damping():
    p = RigParams().replace(Tcu=0.0, dTcu=0.0, bu=0.0, dbu=0.0, Ts=0.0, Tc=0.0, bb=0.0)
    x0 = initial_state(alpha0=0.4, omega_u0=1.2, omega_l0=2.5, x0=2e-3, y0=-1e-3, vx0=0.01)
    tr = simulate("coupled", 0.0, 10.0, params=p, x0=x0)
    E = coupled_energy(tr, p)
    assert np.all(np.diff(E) <= 1e-12 * E[0])
    assert E[-1] < 0.99 * E[0]
