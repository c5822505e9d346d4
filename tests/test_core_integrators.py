"""Integrators: convergence, RK4 against DP5, batch against single runs, input handling."""

import numpy as np
import pytest

from drillgym import RigParams, initial_state, simulate, simulate_batch, BatchSimulator


def test_rk4_converges_on_a_stick_slip_cycle():
    coarse = simulate("torsional", 1.0, 20.0, dt=1e-3)
    fine = simulate("torsional", 1.0, 20.0, dt=2.5e-4, record_every=4)
    assert np.max(np.abs(coarse.omega_l - fine.omega_l)) < 1e-6
    assert np.max(np.abs(coarse.theta_l - fine.theta_l)) < 1e-7


def test_dp5_agrees_with_rk4():
    rk4 = simulate("coupled", 2.0, 10.0, method="rk4")
    dp5 = simulate("coupled", 2.0, 10.0, method="dp5")
    assert np.max(np.abs(rk4.omega_l - dp5.omega_l)) < 1e-6
    assert np.max(np.abs(rk4.r - dp5.r)) < 1e-9
    with pytest.raises(ValueError, match="unknown integration method"):
        simulate("torsional", 1.0, 1.0, method="euler")


def test_batch_equals_single_runs():
    params = [RigParams(), RigParams().scaled(Ts=1.1, Tc=1.1)]
    u = np.stack([np.full(5000, 1.0), np.linspace(0, 3, 5000)])
    batch = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3])
    for k in range(2):
        single = simulate("torsional", u[k], 5.0, params=params[k], alpha0=[0.0, 0.3][k])
        np.testing.assert_allclose(batch.data[k], single.data, rtol=0, atol=1e-12)
    serial = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3])
    parallel = simulate_batch("torsional", u, 5.0, params=params, alpha0=[0.0, 0.3], parallel=True)
    np.testing.assert_array_equal(serial.data, parallel.data)


def test_stepping_interface_matches_simulate():
    sim = BatchSimulator("coupled", n=2)
    sim.reset(alpha0=np.array([0.0, 0.2]))
    for _ in range(300):
        sim.advance(np.array([2.0, 2.0]), n_steps=10)
    ref = simulate("coupled", 2.0, 3.0, alpha0=0.2)
    np.testing.assert_allclose(sim.Y[1], ref.final_state, rtol=0, atol=1e-12)
    assert sim.T[1] == pytest.approx(3.0)


def test_signal_input_is_zero_order_hold():
    t = np.array([0.0, 1.0, 2.0])
    u = np.array([0.0, 2.0, 1.0])
    tr = simulate("upper", (t, u), 3.0)
    assert tr.u[500] == 0.0 and tr.u[1500] == 2.0 and tr.u[2500] == 1.0


def test_bad_inputs_are_refused_with_a_clear_error():
    with pytest.raises(ValueError, match="NaN/inf"):
        simulate("torsional", np.full(1000, np.nan), 1.0)
    with pytest.raises(ValueError, match="unknown configuration 'sideways'"):
        simulate("sideways", 1.0, 1.0)
    with pytest.raises(ValueError, match="duration"):
        simulate("torsional", 1.0, -1.0)
    with pytest.raises(ValueError, match="initial state"):
        simulate("torsional", 1.0, 1.0, x0=np.full(9, np.nan))
    with pytest.raises(ValueError, match="needs 1000"):
        simulate("torsional", np.ones(10), 1.0)


def test_any_voltage_is_accepted_by_the_model():
    tr = simulate("lateral", 50.0, 3.0)
    assert tr.omega_l[-1] > 20.0  # no amplifier limit in the model


def test_free_vibration_keeps_upper_disc_clamped():
    p = RigParams()
    tr = simulate("free_vibration", 0.0, 20.0, alpha0=1.0)
    assert np.all(tr.theta_u == 0.0)
    # lightly damped oscillation at sqrt(ktheta/Jl): speed reversals every half period
    crossings = np.flatnonzero(np.diff(np.sign(tr.omega_l)) != 0)
    period = 2 * np.mean(np.diff(tr.t[crossings[:4]]))
    assert period == pytest.approx(2 * np.pi / np.sqrt(p.ktheta / p.Jl), rel=0.02)
    assert abs(tr.theta_l[-1]) < 0.5


def test_motor_lag_and_input_delay_effects_act():
    base = simulate("upper", 2.0, 1.0)
    lag = simulate("upper", 2.0, 1.0, effects=["motor_lag"], effect_params={"tau_m": 0.1})
    delay = simulate("upper", lambda t: np.where(t >= 0.2, 2.0, 0.0), 1.0, effects=["input_delay"],
                     effect_params={"delay": 0.1})
    assert lag.omega_u[100] < base.omega_u[100]
    assert np.all(delay.omega_u[:300] == 0.0) and delay.omega_u[350] > 0
    assert delay.u[200] == 2.0 and delay.u[199] == 0.0  # the record keeps the commanded voltage
    assert initial_state(alpha0=0.5)[1] == 0.5


def test_simd_lane_kernel_matches_scalar_kernel():
    """Batches of the diagonal-mass configurations run on the SIMD lane kernel; the scalar kernel
    (used for single runs) must give the same runs, events included."""
    from drillgym.simulator import LANES_MIN_BATCH

    volts = np.linspace(0.2, 4.5, LANES_MIN_BATCH * 2)
    alphas = np.linspace(-2.0, 2.0, volts.size)
    for config in ("torsional", "coupled", "lateral"):
        batch = simulate_batch(config, volts, 30.0, alpha0=alphas, record_every=10)
        for k in (0, 5, 11, 15):
            single = simulate(config, volts[k], 30.0, alpha0=alphas[k], record_every=10)
            np.testing.assert_allclose(batch.data[k], single.data, rtol=0, atol=1e-8)
            np.testing.assert_array_equal(batch.stick_l[k], single.stick_l)
        if config != "lateral":
            assert batch.stick_l.mean() > 0.05  # many stick/slip events were crossed
