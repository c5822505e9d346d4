"""A rig that differs from its model: the descent controller holds where the rig's branch is stable,
and the motor-angle loop's limit (near-cancelling RHP poles and zeros) is what the theory says."""

import control
import numpy as np
import pytest

import controllers
from controllers.evaluation import run_closed_loop, run_metrics
from controllers.limits import brake_slope, motor_angle_limit, motor_angle_limits, motor_angle_model
from drillgym import RigParams


def test_descent_holds_3_and_4_rad_s_from_rest_on_rigs_that_differ_from_its_model():
    """Plants off the model by the uncertainty set's edges (km +5 %, bu -10 %, brake static level
    +20 %): the descent holds 3 and 4 rad/s from rest (no stick-slip, mean within 10 %), with the
    controller built on the nominal model; 1 rad/s (unstable branch) is not claimed."""
    p = RigParams()
    plants = [p.replace(km=1.05 * p.km), p.replace(bu=0.9 * p.bu), p.replace(Ts=1.2 * p.Ts)]
    targets = np.array([3.0, 4.0, 1.0])
    P = np.array([q.to_vector() for q in plants for _ in targets])
    ref = np.tile(targets, len(plants))
    c = controllers.make("descent", omega_ref=ref)
    assert c.uses == ("theta_u",) and c.approach_time(1.0) > c.approach_time(9.0)
    run = run_closed_loop(c, "torsional", ref, 60.0, params=P, counts_per_rev=2048, angle_noise=3e-4)
    met = run_metrics(run, 20.0)
    held = (met["ssi"] < 0.1) & (np.abs(met["offset"]) < 0.1)
    assert held[ref > 2].all(), (met["ssi"], met["offset"])
    assert not held[ref == 1.0].any()  # the branch is unstable there: the descent does not hold it
    assert np.all(np.abs(run.u) <= 5.0) and np.all(met["speed_peak"] < 40.0)


def test_descent_checks_its_options():
    with pytest.raises(ValueError, match="hold"):
        controllers.make("descent", omega_ref=1.0, hold=-1.0)
    with pytest.raises(ValueError, match="beyond the amplifier"):
        controllers.make("descent", omega_ref=1.0, approach=50.0)


def test_motor_angle_zeros_are_the_lower_disc_modes_with_the_motor_held_and_nearly_cancel_its_poles():
    p = RigParams()
    lim = motor_angle_limit(p, 1.0)
    s = brake_slope(1.0, p)
    held = np.roots([p.Jl, s, p.ktheta])  # lower disc with theta_u fixed: Jl z^2 + s z + k_theta
    assert s < 0 and sorted(np.real(lim.rhp_zeros)) == pytest.approx(sorted(np.real(held)), rel=1e-6)
    assert len(lim.rhp_poles) == 2 and lim.bound > 500  # poles within a few % of the zeros
    assert motor_angle_limit(p, 3.0).bound == 1.0 and motor_angle_limit(p, 3.0).rhp_poles == ()
    b = [motor_angle_limit(p, w).bound for w in (1.0, 2.0, 2.5)]
    assert b[0] > b[1] > b[2] > 10  # the loop gets easier towards the stable branch, still fragile at 2.5
    with pytest.raises(ValueError, match="positive speed"):
        motor_angle_limit(p, 0.0)


@pytest.mark.parametrize("p", [RigParams(), RigParams().replace(Ts=1.2 * RigParams().Ts, km=0.95 * RigParams().km)])
def test_motor_angle_limits_at_once_are_each_targets_poles_and_control_zeros(p):
    """The batched limits against python-control on each target's model: the poles its state matrix's
    eigenvalues, the zeros control.zeros (to 1e-9), the bound to 1e-9 relative."""
    w = np.linspace(0.5, 4.0, 15)
    lims = motor_angle_limits(p, w)
    assert [g.omega for g in lims] == list(w)
    for g in lims:
        G = motor_angle_model(p, g.omega)
        poles = [z for z in np.linalg.eigvals(np.asarray(G.A)) if z.real > 1e-9]
        zeros = [z for z in control.zeros(G) if z.real > 1e-9]
        assert g.slope == brake_slope(g.omega, p)
        assert sorted(g.rhp_poles, key=abs) == pytest.approx(sorted(poles, key=abs), rel=1e-9)
        assert sorted(g.rhp_zeros, key=abs) == pytest.approx(sorted(zeros, key=abs), rel=1e-9)
        bound = max([1.0] + [np.prod([abs(z + np.conj(q)) / abs(z - q) for z in zeros]) for q in poles])
        assert g.bound == pytest.approx(bound, rel=1e-9)
        assert g == motor_angle_limit(p, g.omega)
    with pytest.raises(ValueError, match="positive speeds"):
        motor_angle_limits(p, [1.0, -1.0])


def test_a_stabilising_lqg_loop_obeys_the_bound():
    """Skogestad-Postlethwaite theorem 5.3 on our model: an LQG controller that stabilises the motor
    angle loop at 2 rad/s has a complementary sensitivity peak at least the computed bound."""
    p = RigParams()
    lim = motor_angle_limit(p, 2.0)
    G = motor_angle_model(p, 2.0)
    A, B, C = np.asarray(G.A), np.asarray(G.B), np.asarray(G.C)
    K, _, _ = control.lqr(A, B, np.diag([1.0, 1.0, 1.0, 10.0]), np.array([[1.0]]))
    L, _, _ = control.lqe(A, np.eye(4), C, np.diag([1e-4, 1e-2, 1e-4, 1e-2]), np.array([[1e-7]]))
    Kc = control.ss(A - B @ K - L @ C, L, -K, 0)  # u = Kc y
    loop = -G * Kc  # positive feedback of u = Kc y written as negative feedback of -G Kc
    T = control.feedback(loop, 1)
    assert np.all(np.real(np.linalg.eigvals(np.asarray(T.A))) < 0)  # it stabilises
    w = np.logspace(-2, 3, 4000)
    peak = np.max(np.abs(T(1j * w)))
    assert peak >= 0.999 * lim.bound


def test_two_encoder_lqg_holds_1_rad_s_on_rigs_that_break_the_motor_angle_observer():
    """With the lower encoder the RHP zeros are gone: the LQG on both encoders, built on the nominal
    model, holds 1 rad/s from rest on plants km +5 %, bu -10 %, brake static level +20 %, Stribeck
    velocity -20 %, with coarse noisy encoders, where the bound forbids any motor-angle-only loop."""
    p = RigParams()
    plants = [p.replace(km=1.05 * p.km), p.replace(bu=0.9 * p.bu), p.replace(Ts=1.2 * p.Ts), p.replace(ws=0.8 * p.ws)]
    assert all(motor_angle_limit(q, 1.0).bound > 100 for q in plants)
    P = np.array([q.to_vector() for q in plants])
    ref = np.full(len(plants), 1.0)
    c = controllers.make("lqg-2enc", omega_ref=ref)
    assert c.uses == ("theta_u", "theta_l") and c.dt == 0.002
    run = run_closed_loop(c, "torsional", ref, 60.0, params=P, counts_per_rev=4096, angle_noise=3e-4)
    met = run_metrics(run, 20.0)
    assert np.all(met["ssi"] < 0.1) and np.all(np.abs(met["offset"]) < 0.1), (met["ssi"], met["offset"])
    with pytest.raises(ValueError, match="tau_ref"):
        controllers.make("lqg-2enc", omega_ref=1.0, tau_ref=0.0)
