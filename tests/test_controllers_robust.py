"""The observer built for a rig that differs from its model: disturbance state, safe fallback, no runaway."""

import numpy as np
import pytest

import controllers
from controllers.evaluation import run_closed_loop, run_metrics
from controllers.evaluation.population import sample_plants
from controllers.kalman import I_DU, disturbance_model
from drillgym import Model, RigParams


def test_upper_disturbance_state_is_a_sixth_state_on_the_upper_disc():
    m5, m6 = disturbance_model(dt=0.002), disturbance_model(dt=0.002, sigma_du=0.002)
    assert m5.Ad.shape == (5, 5) and m6.Ad.shape == (6, 6) and I_DU == 5
    assert np.allclose(m6.Ad[:5, :5], m5.Ad) and m6.Ac[1, I_DU] > 0  # a torque on the upper disc
    assert np.all(m6.Ac[[0, 2, 3, 4], I_DU] == 0)  # and nowhere else (continuous model)
    assert m6.Ad[I_DU, I_DU] == 1.0 and m6.Qd[I_DU, I_DU] > 0
    with pytest.raises(ValueError, match="sigma_du"):
        disturbance_model(sigma_du=-1.0)


def test_overspeed_latches_the_pi_fallback_for_that_rig_only():
    c = controllers.make("observer-robust", omega_ref=[1.0, 1.0])
    assert c.uses == ("theta_u",) and c.dt == 0.002
    c.reset({"theta_u": np.zeros(2)})
    for k in range(1, 200):  # rig 0's motor angle runs away at 30 rad/s, rig 1 stands still
        u = c.act({"theta_u": np.array([30.0 * k * c.dt, 0.0])})
    assert c.safe.tolist() == [True, False]
    assert u[0] < 0.0 and np.all(np.abs(u) <= 5.0)  # the PI loop pulls the runaway motor back to the target
    with pytest.raises(ValueError, match="outer_gain"):
        controllers.make("observer-robust", omega_ref=1.0, outer_gain=-1.0)
    with pytest.raises(ValueError, match="bu_margin"):
        controllers.make("observer-robust", omega_ref=1.0, bu_margin=0.0)
    assert c.params.bu == pytest.approx(controllers.make("pi", omega_ref=1.0).params.bu / 1.1)  # least damped motor


def test_no_run_past_the_over_speed_stop_on_off_model_plants():
    """Three plants from the default uncertainty set (km, friction, lag, delay, coarse noisy encoders),
    short runs: whatever it holds, the robust observer never drives a rig past 40 rad/s."""
    pop = sample_plants(3, seed=11)
    tg = np.array([2.0, 6.0])
    idx = np.repeat(np.arange(3), tg.size)
    ref = np.tile(tg, 3)
    c = controllers.make("observer-robust", omega_ref=ref)
    run = run_closed_loop(
        c,
        "torsional",
        ref,
        15.0,
        params=pop.matrix[idx],
        counts_per_rev=pop.counts_per_rev[idx],
        angle_noise=pop.angle_noise[idx],
        effects=pop.composition,
    )
    met = run_metrics(run, 5.0)
    assert not met["runaway"].any() and np.all(met["u_peak"] <= 5.0)


def test_softtorque_and_lqg_robust_options_are_checked():
    st = controllers.make("softtorque", omega_ref=2.0, km_margin=1.05, bu_margin=1.1)
    assert st.km_model == pytest.approx(1.05 * st.params.km) and st.bu_scale == pytest.approx(1 / 1.1)
    with pytest.raises(ValueError, match="km_margin"):
        controllers.make("softtorque", omega_ref=2.0, km_margin=0.0)
    with pytest.raises(ValueError, match="outer_gain"):
        controllers.make("lqg", omega_ref=2.0, outer_gain=-0.1)


def _robust_model() -> Model:
    return Model(RigParams().replace(Ts=0.3), ("motor_lag",), {"tau_m": 0.03})


def test_the_robust_observer_takes_a_model_and_keeps_its_margin_on_the_models_motor(tmp_path):
    m = _robust_model()
    for given in (m, m.save(tmp_path / "model.json")):
        c = controllers.make("observer-robust", model=given, omega_ref=3.0)
        assert c.effects.label == "motor_lag" and c.effects.values["tau_m"] == pytest.approx(0.03)
        assert c.params.Ts == 0.3 and c.params.bu == pytest.approx(m.params.bu / 1.1)  # least damped motor
        c.reset({"theta_u": np.zeros(1)})
        u = c.act({"theta_u": np.zeros(1)})
        assert np.all(np.isfinite(u))
    c = controllers.make("observer-robust", model=m, omega_ref=3.0, bu_margin=1.0)
    assert c.params.bu == m.params.bu


def test_the_robust_observer_refuses_params_beside_a_different_model_in_one_line():
    with pytest.raises(ValueError, match="either as params or in its model, not both"):
        controllers.make("observer-robust", model=_robust_model(), params=RigParams(), omega_ref=3.0)
