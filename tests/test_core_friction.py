"""Set-valued friction: stick holds at exactly zero speed inside the stick set, releases at its boundary."""

import numpy as np
import pytest

from drillgym import RigParams, simulate
from drillgym.friction import lower_friction, lower_friction_slope, upper_friction


def test_friction_laws_match_model_md():
    p = RigParams()
    w = np.array([0.5, 2.0, 7.0])
    expected = p.Tc + (p.Ts - p.Tc) * np.exp(-(np.abs(w / p.ws) ** p.delta)) + p.bb * w
    np.testing.assert_allclose(lower_friction(w), expected, rtol=1e-12)
    np.testing.assert_allclose(lower_friction(-w), -expected, rtol=1e-12)
    np.testing.assert_allclose(lower_friction(w, brake=False), p.Tcl + p.bl * w, rtol=1e-12)
    np.testing.assert_allclose(upper_friction(w), p.Tcu + p.dTcu + (p.bu + p.dbu) * w, rtol=1e-12)
    np.testing.assert_allclose(upper_friction(-w), -(p.Tcu - p.dTcu + (p.bu - p.dbu) * w), rtol=1e-12)


def test_brake_law_has_negative_damping_region():
    slope = lower_friction_slope(np.array([0.01, 1.0, 10.0]))
    assert slope[0] > 0 and slope[1] < 0 and slope[2] > 0


def test_lower_disc_stays_stuck_inside_stick_set():
    """u = 0.1 V < us: the upper disc winds the string up, the lower disc holds at exactly zero speed."""
    p = RigParams()
    tr = simulate("torsional", 0.1, 300.0, alpha0=0.0, record_every=10)
    assert np.all(tr.omega_l == 0.0)
    assert np.all(tr.theta_l == tr.theta_l[0])
    assert np.all(tr.stick_l == 1.0)
    assert np.all(np.abs(tr.Tfl) <= p.Ts)
    # the upper disc creeps (viscous time constant bu/ktheta = 31 s) until the string holds it
    alpha_end = -(p.km * 0.1 - p.Tcu - p.dTcu) / p.ktheta
    assert tr.alpha[-1] == pytest.approx(alpha_end, rel=1e-3)
    # the holding torque is the string torque: Tfl = -ktheta alpha
    assert tr.Tfl[-1] == pytest.approx(-p.ktheta * tr.alpha[-1], rel=1e-9)


def test_upper_disc_stays_stuck_below_breakaway():
    p = RigParams()
    u = 0.8 * (p.Tcu + p.dTcu) / p.km
    tr = simulate("upper", u, 5.0)
    assert np.all(tr.omega_u == 0.0) and np.all(tr.theta_u == 0.0)
    np.testing.assert_allclose(tr.Tfu, p.km * u, rtol=1e-12)


def test_lower_disc_releases_when_torque_leaves_stick_set():
    """Slow voltage ramp: the lower disc breaks away when the string torque reaches Ts (located to 1e-4)."""
    p = RigParams()
    t_end = 40.0
    tr = simulate("torsional", lambda t: 1.0 * t / t_end, t_end)
    i = int(np.argmax(tr.stick_l < 0.5))
    assert i > 0 and np.all(tr.omega_l[:i] == 0.0)
    torque_at_release = -p.ktheta * tr.alpha[i - 1]
    assert torque_at_release == pytest.approx(p.Ts, rel=2e-3)
    assert tr.omega_l[i] > 0


def test_stuck_disc_under_coupled_dynamics_holds():
    tr = simulate("coupled", 0.1, 10.0, alpha0=0.5)
    assert np.all(tr.omega_l == 0.0)
    assert np.all(np.abs(tr.Tfl) <= RigParams().Ts)


def test_smoothed_friction_is_explicit_and_differs_from_exact():
    exact = simulate("torsional", 1.0, 15.0)
    smooth = simulate("torsional", 1.0, 15.0, friction="smooth", smooth_eps=1e-2)
    assert np.all(smooth.stick_l == 0.0)  # no stick state in the smoothed model
    assert np.min(np.abs(smooth.omega_l[5000:])) > 0.0  # creeps instead of sticking
    assert np.max(exact.omega_l) == pytest.approx(np.max(smooth.omega_l), rel=0.05)
    with pytest.raises(ValueError, match="friction must be"):
        simulate("torsional", 1.0, 1.0, friction="fuzzy")
