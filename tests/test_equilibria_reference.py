"""Equilibria, linearisation and Routh-Hurwitz: R1-R6 of docs/model.md, computed (not tabulated)."""

import control
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from drillgym import RigParams
from drillgym.effects import BASE
from drillgym.equilibria import (
    linearise,
    lower_damping,
    routh_hurwitz_torsional,
    slip_equilibria,
    slip_equilibrium,
    stick_set,
)
from drillgym.errors import ParameterError


@pytest.fixture(scope="module")
def rh():
    return routh_hurwitz_torsional()


def test_r1_critical_damping(rh):
    assert round(rh.dl_critical, 6) == -0.001245


def test_r2_critical_speeds(rh):
    w1, w2 = rh.omega_critical
    assert round(w1, 4) == 0.0608 and round(w2, 4) == 2.8267


def test_r3_hopf_voltages_routh_hurwitz(rh):
    assert [round(u, 4) for u in rh.u_hopf] == [0.1849, 1.6851]


def test_r4_stick_set_exists_only_below_us():
    p = RigParams()
    us = (p.Tcu + p.dTcu + p.Ts) / p.km
    assert round(us, 4) == 0.1509
    assert stick_set("torsional", us - 1e-6) is not None
    assert stick_set("torsional", us + 1e-6) is None
    s = stick_set("coupled", 0.1)
    assert s.alpha_lo < s.alpha_hi


def test_r5_equilibrium_speed_at_3v6():
    eqs = slip_equilibria("torsional", 3.6)
    assert len(eqs) == 1 and round(eqs[0].omega, 2) == 6.24 and eqs[0].stable


def test_r6_lateral_resonance_and_limit():
    p = RigParams()
    res = minimize_scalar(
        lambda w: -slip_equilibrium("lateral", w, with_eigenvalues=False).r,
        bounds=(5, 40),
        method="bounded",
        options={"xatol": 1e-6},
    )
    assert 15.04 <= res.x <= 15.04 * 1.01  # peak at the lateral eigenfrequency sqrt(k/m)
    assert round(np.sqrt(p.k / p.m), 2) == 15.04
    u_peak = slip_equilibrium("lateral", res.x).u
    assert 7.5 < u_peak < 9.0  # "r_eq peaks near u = 8 V"
    r_inf = slip_equilibrium("lateral", 1e4, with_eigenvalues=False).r
    assert round(r_inf * 1e3, 2) == 3.69  # e mr / (mr + mt)


def test_stability_changes_at_hopf_points():
    assert slip_equilibria("torsional", 0.17)[0].stable
    assert not slip_equilibria("torsional", 1.0)[0].stable
    assert slip_equilibria("torsional", 1.7)[0].stable


@pytest.mark.parametrize("config", ["torsional", "coupled", "lateral"])
def test_equilibrium_is_a_rest_point_of_the_simulator(config):
    eq = slip_equilibria(config, 2.5)[0]
    dy, fric = np.zeros(8), np.zeros(2)
    BASE.kernels.model.state_derivative(
        0.0, eq.state, eq.modes, 2.5, RigParams().to_vector(), int(eq.config), 0.0, dy, fric
    )
    assert np.allclose(dy[[2, 3, 6, 7]], 0.0, atol=1e-10)
    assert np.isclose(dy[0], eq.omega) and np.isclose(dy[1], eq.omega)


def test_finite_difference_jacobian_matches_analytic_torsional():
    p = RigParams()
    eq = slip_equilibria("torsional", 1.0)[0]
    du = p.bu + p.dbu
    dl = lower_damping(eq.omega)
    A = np.array([[0, -1, 1], [p.ktheta / p.Ju, -du / p.Ju, 0], [-p.ktheta / p.Jl, 0, -dl / p.Jl]])
    sys = linearise(eq)
    assert isinstance(sys, control.StateSpace)
    assert np.allclose(sys.A, A, rtol=1e-6, atol=1e-8)
    assert np.allclose(sys.B.ravel(), [0, p.km / p.Ju, 0], rtol=1e-6)
    assert sys.state_labels == ["alpha", "omega_u", "omega_l"]


def test_angles_variant_for_observers():
    eq = slip_equilibria("coupled", 3.0)[0]
    sys = linearise(eq, "angles")
    assert sys.state_labels[:4] == ["theta_u", "theta_l", "omega_u", "omega_l"]
    assert sys.output_labels == ["theta_u", "theta_l", "r"]
    lam = np.linalg.eigvals(sys.A)
    assert np.sum(np.abs(lam) < 1e-6) == 1  # the free rotation of the whole rig
    red = np.linalg.eigvals(linearise(eq).A)
    assert np.allclose(np.sort_complex(lam[np.abs(lam) > 1e-6]), np.sort_complex(red), atol=1e-6)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="omega"):
        slip_equilibrium("torsional", 0.0)
    with pytest.raises(ValueError, match="free_vibration"):
        slip_equilibria("free_vibration", 1.0)
    with pytest.raises(ParameterError, match="pf_a1"):
        slip_equilibria("torsional", 1.0, RigParams().replace(pf_a1=0.1))


@pytest.mark.parametrize("config", ["torsional", "coupled"])
def test_equilibria_with_effects_are_rest_points_of_that_model(config):
    """A lag, string damping and a cubic string (user file) move the equilibrium; it is a rest point
    of the composition's own right-hand side, the lag's state sits at the voltage."""
    effects = ["motor_lag", "string_damping", "examples/effects/string_cubic.py:string_cubic"]
    vals = {"tau_m": 0.04, "dtheta": 0.02, "c3": 0.01}
    eq = slip_equilibria(config, 2.5, effects=effects, effect_params=vals)[0]
    base = slip_equilibria(config, 2.5)[0]
    rig = eq.model
    assert abs(eq.alpha - base.alpha) > 1e-3  # the cubic string winds less
    dy = rig.f(eq.state, eq.modes, 2.5, eq.config)
    assert np.allclose(dy[[2, 3, 6, 7, 8]], 0.0, atol=1e-9)
    assert eq.effect_states == pytest.approx((2.5,))
    sys = linearise(eq)
    assert "u_m" in sys.state_labels


def test_effects_without_constant_equilibria_are_refused_naming_them():
    with pytest.raises(ParameterError, match=r"no constant equilibria: its effects \(position_friction\) depend"):
        slip_equilibria(
            "torsional", 2.0, effects=["motor_lag", "position_friction"], effect_params={"pf_c1": 0.2, "tau_m": 0.03}
        )
