"""The worked examples of docs/EFFECTS.md, one per kind of effect, each composed, simulated and checked
against the physics it claims; the Input example (a motor dead zone) also identified on a short recording.
And what the order of Input effects means: the first added is nearest the command."""

from pathlib import Path

import numpy as np
import pytest

from drillgym import RigParams, simulate
from drillgym.effects import compose
from drillgym.effects.base import KINDS
from drillgym.identification import FitVariable, Objective, SegmentedModel, fit_parameters, prepare_experiment
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.measurement import measure_trajectory, quantize_angle

EX = Path(__file__).resolve().parents[1] / "examples" / "effects"
CUBIC = f"{EX}/string_cubic.py:string_cubic"
STICTION = f"{EX}/upper_stiction.py:upper_stiction"
DEAD_ZONE = f"{EX}/motor_dead_zone.py:dead_zone"
SAMPLED = f"{EX}/sampled_command.py:sampled_command"
ECCENTRIC = f"{EX}/encoder_eccentricity.py:encoder_eccentricity"
BACKLASH = f"{EX}/motor_backlash.py:motor_backlash"
P = RigParams()


def test_the_examples_cover_every_kind():
    specs = (CUBIC, STICTION, DEAD_ZONE, SAMPLED, ECCENTRIC, BACKLASH)
    kinds = {compose([spec])[0].effects[0].kind for spec in specs}
    assert kinds == set(KINDS)


def test_friction_example_upper_stiction_needs_the_extra_breakaway_torque():
    ds = 0.2  # N m on top of the upper stick level Tcu + dTcu = 0.374 N m
    hold = (P.Tcu + P.dTcu + 0.5 * ds) / P.km  # V: enough for the base model, not with the stiction
    values = {"ds_u": ds, "vs_u": 0.1}
    base = simulate("upper", hold, 2.0)
    stuck = simulate("upper", hold, 2.0, effects=[STICTION], effect_params=values)
    assert base.omega_u[-1] > 0.01
    assert np.all(stuck.omega_u == 0.0)
    # well above breakaway both turn; the bump slows the start, and fades at speed (exp(-speed / vs_u))
    base = simulate("upper", 1.0, 3.0)
    turning = simulate("upper", 1.0, 3.0, effects=[STICTION], effect_params=values)
    k = int(0.05 / 1e-3)
    assert turning.omega_u[k] < base.omega_u[k] - 1e-3
    assert turning.omega_u[-1] == pytest.approx(base.omega_u[-1], rel=1e-5)


def test_input_example_dead_zone_takes_u0_off_the_voltage():
    values = {"u0": 0.4}
    stuck = simulate("upper", 0.3, 1.0, effects=[DEAD_ZONE], effect_params=values)
    assert np.all(stuck.omega_u == 0.0)  # |u| < u0: the motor gets nothing
    for u in (2.0, -1.5):
        zoned = simulate("upper", u, 2.0, effects=[DEAD_ZONE], effect_params=values)
        base = simulate("upper", u - np.sign(u) * 0.4, 2.0)
        np.testing.assert_allclose(zoned.omega_u, base.omega_u, rtol=0, atol=1e-12)


def test_input_example_dead_zone_is_identified_on_voltage_steps():
    """A 20 s recording of voltage steps (levels held 2-6 s within +-1.5 V) of a rig with a 0.4 V dead zone:
    fitting u0 finds it, and the error falls to the encoders' quantisation."""
    ts = synthetic_measurement(
        "upper",
        duration=20.0,
        rate_hz=250.0,
        signal="steps",
        offset=0.0,
        amplitude=1.5,
        seed=5,
        effects=[DEAD_ZONE],
        effect_params={"u0": 0.4},
    )
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    model = SegmentedModel([ex], 4.0, composition=[DEAD_ZONE])
    obj = Objective(model, {"theta_u": 1.0})
    res = fit_parameters(obj, RigParams(), [FitVariable.of_effect(model.composition, "u0")], max_nfev=20)
    assert res.values["u0"] == pytest.approx(0.4, rel=0.02)
    assert res.rmse_after < 0.1 * res.rmse_before


def test_delay_example_shifts_the_motion_by_computation_time_and_half_a_sample():
    values = {"t_comp": 0.004, "t_sample": 0.01}  # 9 ms: 9 steps of 1 ms
    step = (np.array([0.0, 0.5]), np.array([0.0, 1.0]))
    base = simulate("upper", step, 1.5)
    late = simulate("upper", step, 1.5, effects=[SAMPLED], effect_params=values)
    np.testing.assert_allclose(late.omega_u[9:], base.omega_u[:-9], rtol=0, atol=1e-9)
    assert np.all(late.omega_u[: 500 + 9] == 0.0) and base.omega_u[502] > 0.0


def test_measurement_example_changes_the_reading_not_the_motion():
    values = {"enc_c": 0.004, "enc_s": -0.003}
    comp, vals = compose([ECCENTRIC], values)
    run = simulate("torsional", 1.5, 4.0, effects=comp, effect_params=vals)
    base = simulate("torsional", 1.5, 4.0)
    np.testing.assert_allclose(run.theta_l, base.theta_l, rtol=0, atol=1e-12)  # the motion is the base model's
    zeros = np.zeros_like(run.theta_l)
    tu, tl, _, _ = comp.measure(run.theta_u, run.theta_l, zeros, zeros, comp.vector(P, vals), run.omega_u, run.omega_l)
    np.testing.assert_array_equal(tu, run.theta_u)
    want = run.theta_l + 0.004 * np.cos(run.theta_l) - 0.003 * np.sin(run.theta_l)
    np.testing.assert_allclose(tl, want, rtol=0, atol=1e-12)
    ts = measure_trajectory(run)  # the rig's measurement chain: this effect, then the encoders' quantisation
    np.testing.assert_allclose(ts.theta_l, quantize_angle(want), rtol=0, atol=1e-9)


def _reversing_steps() -> tuple[np.ndarray, np.ndarray]:
    """Voltage steps (s, V) that turn the upper disc both ways."""
    return np.array([0.0, 1.0, 2.5, 4.0, 5.5]), np.array([0.0, 2.5, -2.0, 2.0, -2.5])


def test_a_measurement_may_read_the_speed_the_backlash_example_on_every_path():
    """The motor encoder reads θu + play tanh(ωu / w_play): the motion is the base model's, and the reading is the
    same through the composition, the rig's measurement chain and the environments' sensor kernel."""
    values = {"play": 0.02, "w_play": 0.05}
    comp, vals = compose([BACKLASH], values)
    run = simulate("torsional", _reversing_steps(), 7.0, effects=comp, effect_params=vals)
    base = simulate("torsional", _reversing_steps(), 7.0)
    np.testing.assert_allclose(run.theta_u, base.theta_u, rtol=0, atol=1e-12)
    assert run.omega_u.min() < -0.5 and run.omega_u.max() > 0.5  # it reverses
    zeros = np.zeros_like(run.theta_u)
    p = comp.vector(P, vals)
    tu, tl, _, _ = comp.measure(run.theta_u, run.theta_l, zeros, zeros, p, run.omega_u, run.omega_l)
    want = run.theta_u + 0.02 * np.tanh(run.omega_u / 0.05)
    np.testing.assert_allclose(tu, want, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(tl, run.theta_l)
    np.testing.assert_allclose(measure_trajectory(run).theta_u, quantize_angle(want), rtol=0, atol=1e-9)
    states = np.zeros((run.t.size, comp.n_state))
    states[:, 0], states[:, 1], states[:, 2], states[:, 3] = run.theta_u, run.theta_l, run.omega_u, run.omega_l
    sensors = comp.kernels.client("drillgym.envs.sensor_kernel")
    env_tu = sensors.measured_channels_batch(states, np.tile(p, (run.t.size, 1)))[0]
    np.testing.assert_allclose(env_tu, want, rtol=0, atol=1e-12)


def test_the_backlash_example_is_identified_on_reversing_steps():
    """20 s of steps that reverse the upper disc, read through a 0.02 rad play: fitting the play and its speed
    finds them and the error falls.  The segments' start speeds are fitted too: where the disc starts or reverses,
    the reading's own rate holds the play's change (2 rad/s at the first sample); without room for that the fit
    stays at the start's error (318 -> 307 noise units, play 0.016)."""
    ts = synthetic_measurement(
        "torsional",
        duration=20.0,
        rate_hz=250.0,
        signal="steps",
        offset=0.0,
        amplitude=2.5,
        seed=3,
        effects=[BACKLASH],
        effect_params={"play": 0.02, "w_play": 0.05},
    )
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    model = SegmentedModel([ex], 2.0, composition=[BACKLASH])
    obj = Objective(model, {"theta_u": 1.0, "theta_l": 1.0})
    variables = [FitVariable.of_effect(model.composition, n) for n in ("play", "w_play")]
    res = fit_parameters(obj, RigParams(), variables, max_nfev=30, fit_speeds=True)
    assert res.values["play"] == pytest.approx(0.02, rel=0.01)
    assert res.values["w_play"] == pytest.approx(0.05, rel=0.1)
    assert res.rmse_after < 0.02 * res.rmse_before


def _rhs_and_lag(specs: list[str], u: float, u_m: float) -> tuple[float, float, float]:
    """(voltage at the motor, du_m/dt, u_m after 5 ms exactly) of the generated scalar hooks at one state."""
    comp, vals = compose(specs, {"u0": 0.4, "tau_m": 0.02})
    hooks = comp.kernels.hooks
    y = np.zeros(comp.n_state)
    y[8 + comp.state_index("u_m")] = u_m
    p = comp.vector(P, vals)
    dy = np.zeros(comp.n_state)
    motor = hooks.hk_rhs(0.0, u, y, p, 0, dy)[0]
    yo = y.copy()
    hooks.hk_lag(0.0, u, y, p, 0, 0.005, yo)
    return motor, dy[8], yo[8]


def test_input_effects_act_in_the_order_added_first_nearest_the_command():
    """dead_zone then motor_lag: the lag filters the dead zone's output (tau du_m/dt = dz(u) - u_m, the motor
    sees u_m); motor_lag then dead_zone: the dead zone acts on the lag's output (the motor sees dz(u_m))."""
    u, u_m, decay = 2.5, 1.0, np.exp(-0.005 / 0.02)
    motor, rate, lagged = _rhs_and_lag([DEAD_ZONE, "motor_lag"], u, u_m)
    assert compose([DEAD_ZONE, "motor_lag"])[0].signal_path() == ["dead_zone", "motor_lag"]
    assert (motor, rate) == pytest.approx((u_m, (2.1 - u_m) / 0.02))
    assert lagged == pytest.approx(2.1 + (u_m - 2.1) * decay)
    motor, rate, lagged = _rhs_and_lag(["motor_lag", DEAD_ZONE], u, u_m)
    assert compose(["motor_lag", DEAD_ZONE])[0].signal_path() == ["motor_lag", "dead_zone"]
    assert (motor, rate) == pytest.approx((u_m - 0.4, (u - u_m) / 0.02))
    assert lagged == pytest.approx(u + (u_m - u) * decay)


@pytest.mark.slow
def test_the_order_of_two_input_effects_changes_a_run():
    """On a 2 V step: dead zone then lag is the lag alone on a 1.6 V step; lag then dead zone starts the disc
    later (the motor gets nothing until the lagged voltage passes u0)."""
    vals = {"u0": 0.4, "tau_m": 0.05}
    step = (np.array([0.0, 0.2]), np.array([0.0, 2.0]))
    zone_first = simulate("upper", step, 1.0, effects=[DEAD_ZONE, "motor_lag"], effect_params=vals)
    lag_only = simulate(
        "upper", (step[0], step[1] - 0.4 * (step[1] > 0)), 1.0, effects=["motor_lag"], effect_params={"tau_m": 0.05}
    )
    np.testing.assert_allclose(zone_first.omega_u, lag_only.omega_u, rtol=0, atol=1e-12)
    lag_first = simulate("upper", step, 1.0, effects=["motor_lag", DEAD_ZONE], effect_params=vals)
    start = lambda tr: tr.t[np.argmax(tr.omega_u > 0.0)]  # noqa: E731
    assert start(lag_first) > start(zone_first) + 0.005


def test_the_signal_path_is_given_for_the_json_records_and_printed():
    comp, _ = compose(["string_damping", "motor_lag", SAMPLED, DEAD_ZONE])
    assert comp.signal_path() == ["sampled_command", "motor_lag", "dead_zone"]  # delays first, then Inputs in order
    assert comp.signal_path(among=["dead_zone", "string_damping"]) == ["dead_zone"]
    assert comp.order_fields("dead_zone") == {"kind": "input", "signal_path_position": 3}
    assert comp.order_fields("string_damping") == {"kind": "force"}
    text = comp.describe()
    path = "command -> sampled_command -> motor_lag -> dead_zone -> motor"
    assert f"signal path from the command to the motor: {path}" in text
    assert "order: Input effects act in the order they are added" in text
    assert "signal path" not in compose([DEAD_ZONE])[0].describe()


def test_effects_show_says_what_the_order_of_an_input_effect_means():
    from typer.testing import CliRunner

    from drillgym.cli import app

    r = CliRunner().invoke(app, ["effects", "--show", DEAD_ZONE])
    assert r.exit_code == 0, r.output
    assert "order: Input effects act in the order they are added" in r.output
    assert "the first added is nearest the command" in r.output
