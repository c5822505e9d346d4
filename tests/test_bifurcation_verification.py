"""Independent checks of the periodic branches: periodicity and Floquet multipliers by direct simulation
(drillgym.simulate_batch, exact stick/slip, 10x smaller step), stability labels against simulations from
nearby states, the lateral whirl branch, the section control of the continuation."""

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.bifurcation import equilibrium_branch
from drillgym.bifurcation.continuation import _resection, continue_branch, section_margin
from drillgym.bifurcation.diagram import _hopf_start
from drillgym.bifurcation.poincare import SectionMap
from drillgym.bifurcation.shooting import residual_and_jacobian, shoot
from drillgym.bifurcation.verification import leading_growth, long_run_fate, periodicity_error, simulated_monodromy


def _map(branch, dt=1e-3):
    return SectionMap(branch.config, RigParams().to_vector(), branch.section_speed, dt=dt)


def _section_jacobian(smap, sol):
    _, J, _ = residual_and_jacobian(smap.with_offset(sol.section_offset), sol.z, sol.u)
    return J[:, : smap.dim] + np.eye(smap.dim)


@pytest.fixture(scope="module")
def torsional_unstable():
    """A few points of the unstable slip cycle born at the Hopf point 1.6851 V (torsional)."""
    b = equilibrium_branch("torsional", umax=5.0, n=150)
    sm = _map(b)
    s1 = _hopf_start(sm, b.hopf[1], RigParams(), 0.01)
    br = continue_branch(sm, s1, 1.0, umin=1.6, umax=2.1, ds=0.05, ds_max=0.3, max_points=12)
    return sm, br


def test_unstable_torsional_cycle_multiplier_matches_direct_simulation(torsional_unstable):
    sm, br = torsional_unstable
    sol = max(br.solutions, key=lambda s: abs(s.multipliers[0]))
    lam = abs(sol.multipliers[0])
    assert lam > 1.5 and not sol.stable and not sol.stick_slip
    err, period = periodicity_error(sm, sol)
    assert err < 1e-6 and period == pytest.approx(sol.period, abs=1e-6)
    growth = leading_growth(sm, sol, _section_jacobian(sm, sol), n_returns=3)
    assert np.allclose(growth, lam, rtol=1e-3), (growth, lam)
    # unstable: a 1e-4 push along the leading direction leaves the cycle on both sides
    fate = long_run_fate(sm, sol, _section_jacobian(sm, sol), eps=1e-4, duration=30 * sol.period)
    assert min(fate["plus"]["last"], fate["minus"]["last"]) > 100 * fate["plus"]["first"]


def test_near_hopf_torsional_cycle_multiplier_close_to_one(torsional_unstable):
    sm, br = torsional_unstable
    sol = br.solutions[1]
    M = simulated_monodromy(sm, sol)
    lam_sim = np.max(np.abs(np.linalg.eigvals(M)))
    assert 1.0 < abs(sol.multipliers[0]) < 1.2
    assert lam_sim == pytest.approx(abs(sol.multipliers[0]), rel=1e-4)


@pytest.fixture(scope="module")
def coupled():
    return equilibrium_branch("coupled", umax=5.0, n=150)


def test_coupled_stick_slip_cycle_is_periodic_and_stable(coupled):
    sm = _map(coupled)
    z0 = sm.find_on_orbit(None, 2.0, 20.0)
    sol = shoot(sm, z0, 2.0)
    assert sol.stick_slip and sol.stable
    err, period = periodicity_error(sm, sol)
    assert err < 1e-7 and period == pytest.approx(sol.period, rel=1e-7)
    # the lateral multipliers survive the stick phase: compare the whole spectrum (dt 0.25 ms: 4x finer)
    ms = np.sort(np.abs(np.linalg.eigvals(simulated_monodromy(sm, sol, dt=2.5e-4))))[::-1]
    assert 1e-3 < ms[0] < 0.1
    assert np.allclose(ms[:4], np.abs(sol.multipliers[:4]), atol=2e-4, rtol=1e-2)
    fate = long_run_fate(sm, sol, _section_jacobian(sm, sol), eps=1e-3, duration=20 * sol.period)
    assert fate["plus"]["last"] < 1e-6 and fate["minus"]["last"] < 1e-6


def test_coupled_unstable_cycle_multiplier_and_label(coupled):
    sm = _map(coupled)
    s1 = _hopf_start(sm, coupled.hopf[1], RigParams(), 0.01)
    br = continue_branch(sm, s1, 1.0, umin=1.6, umax=1.9, ds=0.05, ds_max=0.3, max_points=6)
    sol = br.solutions[-1]
    assert not sol.stable and abs(sol.multipliers[0]) > 1.05
    g = leading_growth(sm, sol, _section_jacobian(sm, sol), n_returns=2)
    assert np.allclose(g, abs(sol.multipliers[0]), rtol=2e-3)


@pytest.fixture(scope="module")
def lateral():
    return equilibrium_branch("lateral", umax=50.0, n=300)


def test_section_speed_is_the_exact_equilibrium_speed(lateral):
    for h in lateral.hopf:
        assert lateral.section_speed(h.u) == pytest.approx(h.omega, abs=1e-8)


def test_lateral_whirl_branch_from_the_first_hopf_point(lateral):
    h = lateral.hopf[0]
    assert 8.7 < h.u < 8.85
    sm = _map(lateral)
    sol = _hopf_start(sm, h, RigParams(), 0.003)
    assert sol.u == pytest.approx(h.u, abs=2e-4)
    assert sol.period == pytest.approx(2 * np.pi / h.frequency, rel=1e-2)
    err, period = periodicity_error(sm, sol)
    assert err < 1e-7 and period == pytest.approx(sol.period, rel=1e-6)
    lam = sol.multipliers[0]
    growth = leading_growth(sm, sol, _section_jacobian(sm, sol), eps=1e-6, n_returns=1)
    assert growth[0] == pytest.approx(abs(lam), abs=2e-3)
    assert sol.stable == (abs(lam) < 1)


def test_section_is_moved_away_from_an_extremum_of_omega_l():
    """Put the section just below the orbit's top speed: the control moves it to the middle of the
    orbit and the re-shot point is the same cycle (same period)."""
    b = equilibrium_branch("torsional", umax=5.0, n=150)
    sm = _map(b)
    sol = shoot(sm, sm.find_on_orbit(None, 2.0, 30.0), 2.0)
    ws = b.section_speed(2.0)
    near_top = sm.with_offset(sol.omega_l_max - 0.02 * (sol.omega_l_max - sol.omega_l_min) - ws)
    sol_top = shoot(near_top, near_top.find_on_orbit(None, 2.0, 30.0), 2.0)
    margin, offset = section_margin(near_top, sol_top)
    assert margin < 0.05 and offset is not None
    moved = _resection(near_top, sol_top)
    assert moved is not None
    new_map, new_sol = moved
    assert section_margin(new_map, new_sol)[0] > 0.2
    assert new_sol.period == pytest.approx(sol.period, rel=1e-6)
    assert new_sol.section_offset == pytest.approx(offset)
