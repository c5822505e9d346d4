"""The command's path to the motor in the residual torques, and motor-side candidates read through it."""

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.diagnosis.discovery import Candidate
from drillgym.diagnosis.discovery_terms import dead_zone_variant
from drillgym.diagnosis.sparse import motor_voltage_along, residual_torques
from drillgym.effects import Input, Parameter, compose
from drillgym.identification.experiment import prepare_experiment
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.params import PARAM_NAMES

TAU, DELAY = 0.03, 0.02


class VoltageOffset(Input):
    """The motor sees the voltage plus a constant offset (a user's effect, outside the library)."""

    name = "voltage_offset_for_test"
    parameters = (Parameter("u_off", "V", -1.0, 1.0, 0.0, 0.05, "offset", neutral=0.0),)

    def voltage(u, u_off):
        return u + u_off


def _steps(effects, **values):
    """15 s of voltage steps at 250 Hz from the simulator, with ``effects`` at ``values``."""
    ts = synthetic_measurement(
        "torsional",
        None,
        duration=15.0,
        rate_hz=250.0,
        signal="steps",
        offset=1.5,
        seed=3,
        effects=effects,
        effect_params=values or None,
    )
    return prepare_experiment(ts, compare_rate_hz=250.0)


def test_the_voltage_at_the_motor_is_the_command_delayed_then_lagged():
    """A lag of 30 ms after a delay of 20 ms: the voltage along the recording is the first-order filter of the
    command shifted by the delay (the first value held before the start), exactly at every sample."""
    ex = _steps(["input_delay", "motor_lag"], delay=DELAY, tau_m=TAU)
    comp, vals = compose(["input_delay", "motor_lag"], {"delay": DELAY, "tau_m": TAU})
    p = comp.vector(RigParams(), vals)
    Y = np.zeros((ex.n, comp.n_state))
    v = motor_voltage_along(ex, comp, p, Y)
    dt = 1.0 / ex.fs
    shifted = ex.input_on_grid(dt, ex.n, ex.t[0] - DELAY)
    assert np.allclose(v.command, shifted)
    assert not np.allclose(shifted, ex.input_on_grid(dt, ex.n, ex.t[0]))  # the delay moved the steps
    expected = np.empty(ex.n)
    expected[0] = shifted[0]
    decay = np.exp(-dt / TAU)
    for i in range(1, ex.n):
        expected[i] = shifted[i - 1] + (expected[i - 1] - shifted[i - 1]) * decay
    assert np.allclose(v.at_motor, expected, atol=1e-9)


def test_residual_torques_are_smaller_with_the_lag_the_recording_has():
    """On steps with a 30 ms motor lag, the residual torque on the upper disc of the model with that lag is far
    below the one of the base model (whose motor sees the command at once)."""
    ex = _steps(["motor_lag"], tau_m=TAU)
    comp, vals = compose(["motor_lag"], {"tau_m": TAU})
    with_lag = residual_torques(ex, comp.vector(RigParams(), vals), effects=comp)
    base = residual_torques(ex)

    def power(rt):
        return float(np.nanmean(rt.tau_u[rt.upper_valid] ** 2))

    assert power(with_lag) < 0.5 * power(base), (power(with_lag), power(base))
    assert with_lag.u_motor is not None and not np.allclose(with_lag.u_motor, base.u_motor)


def _candidate(terms):
    return Candidate("motor_voltage", dict(terms), {k: "1.0" for k in terms}, dict.fromkeys(terms, 0.0), 0.9, 100)


def test_a_negative_offset_is_also_read_as_a_dead_zone():
    """A constant −0.4 V among the voltage terms (what a dead zone of 0.4 V is on one-signed voltages) gets a
    variant with −sat(u, 0.4) in its place, the other terms kept; a positive offset or a candidate with a dead
    zone already has none."""
    variant = dead_zone_variant(_candidate({"1": -0.4, "u|u|": 0.01}))
    assert variant is not None
    assert variant.terms == {"sat(u, 0.4)": -1.0, "u|u|": 0.01}
    assert variant.widths == {"sat(u, 0.4)": pytest.approx(0.4)}
    assert "min(max(u, -U0), U0)" == variant.codes["sat(u, 0.4)"]
    assert dead_zone_variant(_candidate({"1": 0.2})) is None
    whole = _candidate({"sat(u, 0.3)": -1.0})
    whole.widths = {"sat(u, 0.3)": 0.3}
    assert dead_zone_variant(whole) is None


def test_a_mixed_shift_of_the_voltage_is_read_as_one_dead_zone():
    """A partial zone beside an offset (−0.39 sat(u, 0.5) − 0.21: what a regression on steps whose turning levels
    all lie beyond 0.5 V takes for a 0.4 V dead zone) is read as one zone of the shift they make together on the
    recording's commands beyond 0.5 V, the other terms kept; on commands that never pass the zone there is none."""
    cand = _candidate({"sat(u, 0.5)": -0.39, "u³": -0.0034, "1": -0.21})
    cand.widths = {"sat(u, 0.5)": 0.5}
    u = np.repeat([2.7, -0.1, 0.01, 1.23, 1.06, 1.33, 0.45], 100)
    variant = dead_zone_variant(cand, u)
    assert variant is not None
    (zone,) = (k for k in variant.terms if k.startswith("sat(u"))
    assert variant.terms[zone] == -1.0 and variant.terms["u³"] == -0.0034 and "1" not in variant.terms
    assert variant.widths[zone] == pytest.approx(0.39 * 0.5 + 0.21)
    assert dead_zone_variant(cand, np.full(10, 0.3)) is None


def test_a_dead_zone_behind_an_unselected_lag_is_found_through_the_lag():
    """Ramps through a 30 ms lag then a 0.4 V dead zone (drillgym's simulator, the user's dead-zone file), the
    base model diagnosed (no lag selected): the motor side's candidate is regressed through a lag of the grid
    next to 30 ms (it leaves less than half the residual the same search without a lag leaves)."""
    from types import SimpleNamespace

    from drillgym.diagnosis import discovery

    dead_zone = "examples/effects/motor_dead_zone.py:dead_zone"
    rng = np.random.default_rng(4)
    knots = np.cumsum(rng.uniform(3.0, 8.0, 6))
    t = np.arange(0.0, 20.0, 1e-3)
    u = np.interp(t, np.r_[0.0, knots], np.r_[1.0, 1.0 + 1.6 * rng.uniform(-1.0, 1.0, knots.size)])
    ts = synthetic_measurement(
        "torsional",
        None,
        duration=20.0,
        rate_hz=250.0,
        input=(t, u),
        seed=4,
        effects=["motor_lag", dead_zone],
        effect_params={"tau_m": TAU, "u0": 0.4},
    )
    ex = prepare_experiment(ts, compare_rate_hz=250.0)
    base = SimpleNamespace(composition=None, vector=RigParams().to_vector(), selected=[], at_bounds=[])
    cand = discovery._motor_side_candidate(ex, base)
    # on one-signed voltages the dead zone is a constant: km × (−0.4 V) at the motor, or that torque on the disc
    assert cand is not None and cand.group in ("motor_voltage", "upper_force"), cand
    assert cand.through_lag in (0.02, 0.04), cand.through_lag  # the grid's neighbours of 30 ms


def test_a_candidate_fit_worse_than_none_says_so():
    """A candidate whose fit leaves more than the model without it (a negative cut) is not reported as removing a
    share of the residual."""
    from drillgym.diagnosis.candidate_fit import CandidateFit
    from drillgym.diagnosis.unexplained import Unexplained

    worse = CandidateFit({"c1": 0.1}, True, Unexplained(300.0, {"theta_u": 300.0}), Unexplained(2600.0, {}))
    assert worse.variance_cut < 0
    assert "explains none of it" in worse.line() and "%" not in worse.line()
    better = CandidateFit({"c1": 0.1}, False, Unexplained(300.0, {}), Unexplained(30.0, {}))
    assert "99% of the unexplained variance removed" in better.line()


def test_the_motor_side_is_looked_at_on_the_nominal_base_when_the_diagnosis_left_one_at_a_bound():
    """A −0.15 V voltage offset on steps (drillgym's simulator, an offset written as a user's Input effect), diagnosed
    with the motor constant taken 12 % down to its bound: on that model's residual the offset is partly hidden, on
    the nominal base it is the whole residual; the motor side's candidate is the offset's torque found there."""
    from types import SimpleNamespace

    from drillgym.diagnosis import discovery

    ex = _steps([VoltageOffset], u_off=-0.15)
    nominal = RigParams().to_vector()
    at_bound = nominal.copy()
    at_bound[PARAM_NAMES.index("km")] *= 0.88
    diagnosed = SimpleNamespace(composition=None, vector=at_bound, selected=[], at_bounds=["km"], nominal_vector=None)
    alone = discovery._motor_side_candidate(ex, diagnosed)
    cand = discovery._motor_side_candidate(ex, SimpleNamespace(**{**vars(diagnosed), "nominal_vector": nominal}))
    assert cand is not None and cand.explained > 0.9 and cand.through_lag is None, cand
    # on one-signed steps the offset is a constant torque: km × u_off at the motor, or on the upper disc
    torque = cand.terms["1"] * (RigParams().km if cand.group == "motor_voltage" else 1.0)
    assert torque == pytest.approx(-0.15 * RigParams().km, rel=0.05), cand
    assert alone is None or cand.explained > alone.explained, (cand, alone)


def test_the_selected_timing_is_fitted_with_a_voltage_candidate():
    """A change of the motor's voltage is fitted with the selected effects on its signal path (a delay, a lag),
    which may have stood in for it (a dead zone on steps selected as a 200 ms delay), not with the others (string
    damping); a torque on the upper disc is fitted beside them as regressed."""
    from types import SimpleNamespace

    from drillgym.diagnosis.candidate_fit import _selected_rest, _stood_in
    from drillgym.effects import compose

    comp, _ = compose(["input_delay", "motor_lag", "string_damping"], None)
    diagnosis = SimpleNamespace(composition=comp, selected=["input_delay", "string_damping", "motor_lag"])
    assert _stood_in(diagnosis, _candidate({"1": -0.3})) == ("delay", "tau_m")
    torque = _candidate({"cos θu": 0.01})
    torque.group = "upper_force"
    assert _stood_in(diagnosis, torque) == ()
    # the freer fit, tried when the first leaves the recording above the noise, frees every other selected effect
    # (a brake asymmetry a drive offset was taken for), never one the selection did not take
    comp, _ = compose(["input_delay", "motor_lag", "string_damping", "brake_asymmetry"], None)
    diagnosis = SimpleNamespace(composition=comp, selected=["brake_asymmetry", "input_delay"])
    assert _selected_rest(diagnosis, _stood_in(diagnosis, _candidate({"1": 0.1}))) == ("asym_s", "asym_c")
    assert _selected_rest(diagnosis, ()) == ("delay", "asym_s", "asym_c")


def test_a_lag_the_base_could_take_is_left_to_the_lag(tmp_path):
    """On the independent motor rig (benchmarks/bench_diagnosis_motor.py: scipy, smoothed friction, its own
    measurement chain), a −0.12 V drive offset beside a 31 ms motor lag, 20 s of steps at 250 Hz, base parameters
    up to 5 % off: freed beside the voltage candidate, the base took the lag's share by moving km, Tcu, bu, Ts and
    Tc 8-15 % (19 noise units left, no lag found after); such a base is not "a few percent off", so the candidate
    is fitted with the base as diagnosed and the lag is selected beside it."""
    import sys
    from pathlib import Path

    from drillgym.diagnosis import diagnose

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_diagnosis_motor import motor_recording

    scale = {"km": 1.011776, "bu": 1.022289, "Tcu": 0.950496, "Ts": 0.973126, "Tc": 0.966392, "ktheta": 1.042596}
    scale["Jl"] = 1.047363
    effects = {"voltage_offset": {"u_off": -0.124247}, "motor_lag": {"tau_m": 0.031324}}
    ts = motor_recording("steps", 20.0, 250.0, 16, effects, scale)
    d = diagnose(ts, discover=True, candidate_out=tmp_path / "candidate.py")
    fit = d.candidate.fit
    assert d.candidate.group == "motor_voltage" and fit.variance_cut > 0.5
    moved = [abs(v) for v in fit.base_fitted.values()]
    assert not moved or max(moved) < 8.0, fit.base_fitted
    assert d.reselection is not None and "motor_lag" in d.reselection.selected, d.reselection.selected
    assert d.reselection.unexplained.ratio_to_noise < 10.0
