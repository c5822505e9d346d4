"""Every effect through every simulation path of the core, against the single-run reference.

One composition holds all ten library effects at once (coupled: brake and lateral motion, the
command turns negative so the brake asymmetry acts), another the two user example files.  The
paths: the scalar kernel of a single run (the reference), the SIMD lane kernel of a batch, the
stepping interface (scalar and lane kernels, command held over control periods as the envs and the
emulator do), the smoothed-friction and DP5 options, and the measurement chain.
"""

from pathlib import Path

import numpy as np
import pytest

from drillgym import BatchSimulator, simulate, simulate_batch
from drillgym.effects import LIBRARY, compose
from drillgym.measurement import MeasurementModel, measure_trajectory
from drillgym.simulator import LANES_MIN_BATCH

ROOT = Path(__file__).resolve().parents[1]
ALL_LIBRARY = list(LIBRARY)
LIBRARY_VALUES = {
    "pf_c1": 0.12,
    "pf_s2": -0.05,
    "asym_s": 0.3,
    "asym_c": 0.2,
    "dtheta": 0.004,
    "tau_m": 0.03,
    "delay": 0.0237,
    "dk": 150.0,
    "db": 2.0,
    "lvdt_x0": 2e-4,
    "lvdt_y0": -1e-4,
    "lvdt_skew": 0.03,
    "Fc_lat": 1.5,
    "drift": 0.004,
}
USER = [
    f"{ROOT}/examples/effects/string_cubic.py:string_cubic",
    f"{ROOT}/examples/effects/string_backlash.py:string_backlash",
]
USER_VALUES = {"c3": 0.015, "gap": 0.05}
DT = 1e-3
PERIOD = 10  # steps per control period of the stepping paths
DURATION = 12.0


def command(n_steps: int) -> np.ndarray:
    """A command piecewise constant over control periods: steps, a slow sine through zero."""
    t = np.arange(n_steps) * DT
    u = 2.2 * np.sin(0.6 * t) + 1.2 * (t > 4.0) - 0.8 * (t > 8.5)
    return np.repeat(u[::PERIOD], PERIOD)[:n_steps]


CASES = [
    ("coupled", ALL_LIBRARY, LIBRARY_VALUES),
    ("torsional", USER, USER_VALUES),
    ("lateral", ["lateral_anisotropy", "motor_lag", "input_delay"], LIBRARY_VALUES),
]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] + "-" + str(len(c[1])) for c in CASES])
def case(request):
    config, effects, values = request.param
    comp, vals = compose(effects, {k: v for k, v in values.items() if k in compose(effects)[0].param_names})
    n = int(round(DURATION / DT))
    U = command(n)
    ref = simulate(config, U, DURATION, dt=DT, effects=comp, effect_params=vals, alpha0=0.3)
    return config, comp, vals, U, ref


def test_effects_change_the_run(case):
    config, comp, vals, U, ref = case
    base = simulate(config, U, DURATION, dt=DT, alpha0=0.3)
    assert np.max(np.abs(ref.omega_l - base.omega_l)) > 0.05
    if "u_m" in comp.state_names:
        assert np.max(np.abs(ref.u_m - ref.u)) > 0.1  # the lag's state is recorded and lags the command


@pytest.mark.slow
def test_batch_lanes_match_single_run(case):
    config, comp, vals, U, ref = case
    B = LANES_MIN_BATCH
    batch = simulate_batch(
        config, np.tile(U, (B, 1)), DURATION, dt=DT, effects=comp, effect_params=vals, alpha0=np.full(B, 0.3)
    )
    for k in (0, B - 1):
        np.testing.assert_allclose(batch.data[k], ref.data, rtol=0, atol=1e-8)


@pytest.mark.parametrize("n", [1, LANES_MIN_BATCH])
def test_stepping_matches_single_run(case, n):
    """Command held over control periods (the envs', harness' and emulator's path), scalar (n = 1)
    and lane (n = 8) kernels, delay lines and effect states carried between calls."""
    config, comp, vals, U, ref = case
    sim = BatchSimulator(config, n, dt=DT, effects=comp, effect_params=vals)
    sim.reset(alpha0=0.3)
    for i in range(0, U.size, PERIOD):
        sim.advance(np.full(n, U[i]), PERIOD)
    final = ref.final_state
    for k in range(n):
        np.testing.assert_allclose(sim.Y[k], final, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sim.T, DURATION, rtol=1e-12)


def test_dp5_and_smooth_options_run_the_same_effects(case):
    config, comp, vals, U, ref = case
    dp5 = simulate(config, U, DURATION, dt=DT, effects=comp, effect_params=vals, alpha0=0.3, method="dp5")
    assert np.max(np.abs(dp5.omega_l - ref.omega_l)) < 0.05
    smooth = simulate(
        config, U, DURATION, dt=DT, effects=comp, effect_params=vals, alpha0=0.3, friction="smooth", smooth_eps=1e-3
    )
    assert np.all(np.isfinite(smooth.data))


def test_measurement_effects_act_on_readings_not_dynamics():
    # measurement effects act in the order given: the skewed axis first, then the reading's offset
    comp, vals = compose(["lvdt_skew", "lvdt_offset"], {"lvdt_x0": 1e-3, "lvdt_y0": -2e-3, "lvdt_skew": 0.05})
    tr = simulate("lateral", 6.0, 4.0, effects=comp, effect_params=vals)
    base = simulate("lateral", 6.0, 4.0)
    # the dynamics do not see them (another compiled module: equal to rounding, FMA contraction may differ)
    np.testing.assert_allclose(tr.data[:, :18], base.data[:, :18], rtol=0, atol=1e-12)
    m = measure_trajectory(tr, MeasurementModel(lvdt_noise_std=0.0, lvdt_lowpass_hz=None))
    X, Y = tr.x, tr.y
    np.testing.assert_allclose(m.columns["x"], X + 1e-3, atol=1e-15)
    np.testing.assert_allclose(m.columns["y"], Y * np.cos(0.05) + X * np.sin(0.05) - 2e-3, atol=1e-15)


def test_input_delay_shifts_the_response_by_the_delay():
    """A step delayed by d: the motor starts d later; the recorded u stays the command."""
    u = lambda t: np.where(t >= 0.5, 3.0, 0.0)  # noqa: E731
    base = simulate("upper", u, 2.0)
    late = simulate("upper", u, 2.0, effects=["input_delay"], effect_params={"delay": 0.25})
    np.testing.assert_allclose(late.omega_u[750:], base.omega_u[500:-250], atol=1e-12)
    np.testing.assert_array_equal(late.u, base.u)


def test_backlash_is_a_dead_zone_of_the_string():
    """Free vibration (upper disc clamped) released inside the gap: no string torque, the lower disc
    only feels its bearing; released outside: it oscillates about the gap's edge."""
    spec = f"{ROOT}/examples/effects/string_backlash.py:string_backlash"
    inside = simulate("free_vibration", 0.0, 2.0, alpha0=0.03, effects=[spec], effect_params={"gap": 0.05})
    assert np.all(inside.omega_l == 0.0)  # bearing stick holds it: no torque inside the play
    outside = simulate("free_vibration", 0.0, 6.0, alpha0=0.5, effects=[spec], effect_params={"gap": 0.05})
    linear = simulate("free_vibration", 0.0, 6.0, alpha0=0.45)
    assert np.max(np.abs(outside.omega_l[:1000] - linear.omega_l[:1000])) < 1e-9  # shifted by the gap exactly


def test_a_run_restarted_in_the_middle_continues_the_whole_run():
    """t0 and u_before (the commands before the start, for the delay line) let a segment of a run be
    simulated on its own: drift sees the real time, the delay the earlier commands."""
    comp, vals = compose(["input_delay", "friction_drift", "motor_lag"], {"delay": 0.05, "drift": 0.01, "tau_m": 0.02})
    n = 6000
    U = command(n)
    whole = simulate("torsional", U, n * DT, effects=comp, effect_params=vals, alpha0=0.3)
    i = 3000
    seg = simulate_batch(
        "torsional",
        U[None, i:],
        (n - i) * DT,
        effects=comp,
        effect_params=vals,
        x0=whole.data[i, list(range(2, 10)) + [18]],
        t0=i * DT,
        u_before=U[:i],
    )
    np.testing.assert_allclose(seg.data[0, -1, 2:10], whole.data[-1, 2:10], atol=1e-9)
    np.testing.assert_allclose(seg.t[0], whole.t[i:], atol=1e-9)


def test_recording_only_some_columns_gives_the_same_values():
    volts = np.linspace(0.5, 4.0, LANES_MIN_BATCH)
    full = simulate_batch("coupled", volts, 3.0, record_every=7)
    some = simulate_batch("coupled", volts, 3.0, record_every=7, record=("omega_l", "r", "t"))
    assert some.data.shape == full.data.shape[:2] + (3,)
    # Each column set is its own compiled kernel, vectorised as LLVM sees fit; the flags change no finite value
    # (drillgym.vmath.FASTMATH), so they give the same bits
    np.testing.assert_array_equal(some.omega_l, full.omega_l)
    np.testing.assert_array_equal(some.r, full.r)
    np.testing.assert_array_equal(some.t, full.t)
    one = simulate("torsional", 1.0, 2.0, record=["Tfl"], effects=["motor_lag"])
    np.testing.assert_array_equal(one.Tfl, simulate("torsional", 1.0, 2.0, effects=["motor_lag"]).Tfl)
    with pytest.raises(AttributeError, match="not recorded"):
        _ = one.omega_l
    with pytest.raises(ValueError, match="unknown column 'speed'"):
        simulate("torsional", 1.0, 1.0, record=("speed",))


def test_effects_at_their_neutral_values_leave_a_batch_as_the_base_model():
    """Nine library effects (all but motor_lag, which declares no neutral value) at their neutral
    values: the batch skips them and runs as the base model; with one lane's position friction on,
    the batch runs them all, that lane changes and the others still equal the base model."""
    effects = [e for e in ALL_LIBRARY if e != "motor_lag"]
    comp, _ = compose(effects)
    neutral = {p.name: p.neutral for e in comp.effects for p in e.parameters}
    assert None not in neutral.values()
    B = LANES_MIN_BATCH
    n = int(round(DURATION / DT))
    U = np.tile(command(n), (B, 1))
    base = simulate_batch("coupled", U, DURATION, dt=DT, alpha0=np.full(B, 0.3))
    P = comp.matrix(None, B, neutral)
    off = simulate_batch("coupled", U, DURATION, dt=DT, effects=comp, params=P, alpha0=np.full(B, 0.3))
    P[-1, comp.param_index("pf_c1")] = 0.12
    on = simulate_batch("coupled", U, DURATION, dt=DT, effects=comp, params=P, alpha0=np.full(B, 0.3))
    cols = base.data[0].shape[1]
    for k in range(B - 1):
        np.testing.assert_allclose(off.data[k][:, :cols], base.data[k], rtol=0, atol=1e-9)
        np.testing.assert_allclose(on.data[k][:, :cols], base.data[k], rtol=0, atol=1e-9)
    assert np.max(np.abs(on.data[-1][:, :cols] - base.data[-1])) > 0.05


def test_an_effect_file_written_again_is_imported_again(tmp_path):
    """A file replaced in the same process (an edited effect, a candidate file diagnose wrote again) is read
    again: the first import is not served for the new content."""
    from drillgym.effects.registry import load_class_from_file

    path = tmp_path / "edited.py"
    head = "from drillgym.effects import Force, Parameter\n\n\n"
    body = (
        "class {cls}(Force):\n    name = '{name}'\n    acts_on = 'upper'\n"
        "    parameters = (Parameter('{par}', 'N m', -1.0, 1.0, 0.0, 0.01, 'torque', neutral=0.0),)\n\n"
        "    def torque({par}):\n        return {par}\n"
    )
    path.write_text(head + body.format(cls="First", name="first", par="t_first"), encoding="utf-8")
    assert load_class_from_file(path, "first").name == "first"
    path.write_text(head + body.format(cls="Second", name="second", par="t_second"), encoding="utf-8")
    assert load_class_from_file(path, "second").parameters[0].name == "t_second"
