"""Diagnosis as model selection: several effects at once, a base model a few percent off.

Recordings: drillgym's simulator through the rig's measurement chain (``synthetic_measurement``) and the
independent rig of ``benchmarks/bench_diagnosis_rig.py`` (scipy, smoothed friction).  The diagnosis is
never told what is hidden.  :func:`independent_rig` and :func:`recording` serve the other
``test_diagnosis_*`` files too.
"""

from pathlib import Path

import pytest

from drillgym import RigParams
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.context import BASE_BOUNDS, BRAKE_BOUNDS, base_range
from drillgym.diagnosis.search_model import neutral_values, search_composition
from drillgym.effects import BASE, LIBRARY
from drillgym.identification.synthetic import synthetic_measurement

MISMATCH = {"Ts": 1.06, "km": 0.97, "Jl": 1.04}


def independent_rig():
    """``rig_recording`` of benchmarks/bench_diagnosis_rig.py: recordings made by a simulator other than drillgym's."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_diagnosis_rig import rig_recording

    return rig_recording


def recording(params=None, effects=None, **values):
    """20 s of a simulated torsional recording at 250 Hz (quasi-random input about 1 V), hidden ``effects`` in it."""
    return synthetic_measurement(
        "torsional",
        params,
        duration=20.0,
        rate_hz=250.0,
        offset=1.0,
        seed=5,
        effects=effects,
        effect_params=values or None,
    )


def test_two_effects_found_as_a_set():
    d = diagnose(recording(effects=["position_friction", "motor_lag"], pf_c1=0.12, pf_s1=-0.08, tau_m=0.03))
    assert set(d.selected) == {"position_friction", "motor_lag"}, d.text()
    vals = d.effect_values()
    assert vals["tau_m"] == pytest.approx(0.03, rel=0.2)
    assert vals["pf_c1"] == pytest.approx(0.12, rel=0.2) and vals["pf_s1"] == pytest.approx(-0.08, rel=0.2)
    assert d.rmse_after < 0.1 * d.rmse_before
    assert [s.effect for s in d.ranking[:2]] == d.selected and all(s.significant for s in d.ranking[:2])
    assert not any(s.significant for s in d.ranking[2:])
    assert d.to_json()["lag_delay"] is None  # 250 Hz: too slow for the check at the recording's rate


def test_plain_mismatch_is_not_an_effect_and_moved_parameters_are_named():
    d = diagnose(recording(RigParams().scaled(**MISMATCH)))
    assert d.selected == [], d.text()
    assert d.base_off
    moved = d.base_parameters
    assert moved and set(moved) & set(MISMATCH), moved
    for m in moved.values():  # each entry names nominal, fitted and the change
        assert m.change_pct == pytest.approx(100 * (m.fitted / m.nominal - 1))
    for name in set(moved) & set(MISMATCH):  # the parameters that were off moved the right way
        assert (moved[name].change_pct > 0) == (MISMATCH[name] > 1), moved
    assert "base model is off" in d.text()


def test_effect_found_under_mismatch_with_its_value():
    d = diagnose(recording(RigParams().scaled(**MISMATCH), effects=["motor_lag"], tau_m=0.03))
    assert d.selected in (["motor_lag"], ["input_delay"]), d.text()
    if d.selected == ["input_delay"]:  # only as a stated tie
        assert "indistinguishable" in d.ranking[0].note
    else:
        assert d.effect_values()["tau_m"] == pytest.approx(0.03, rel=0.25)
    assert d.base_parameters, d.text()


def test_a_brake_further_off_than_a_few_percent_is_re_identified_not_pinned_at_a_bound():
    """The brake's level and Stribeck law move by tens of per cent between runs of one rig (the population's
    uncertainty set draws them ±20 %): re-identified inside their own range, with the effect beside them found,
    not left at the ±12 % bound of the other base parameters with the effect dropped."""
    rig = RigParams().scaled(Ts=1.18, Tc=0.83, ws=1.15)
    d = diagnose(recording(rig, effects=["position_friction"], pf_c1=0.08, pf_s1=-0.05), discover=False)
    assert d.selected == ["position_friction"] and d.at_bounds == [], d.text()
    for name, factor in (("Ts", 1.18), ("Tc", 0.83), ("ws", 1.15)):
        assert d.base_parameters[name].change_pct == pytest.approx(100 * (factor - 1), abs=2.0), d.base_parameters
    # the motor's side keeps the narrow range: a lag is not absorbed by km and bu scaled alike
    p = RigParams()
    assert base_range("km", p.km) == pytest.approx((BASE_BOUNDS[0] * p.km, BASE_BOUNDS[1] * p.km))
    assert base_range("Ts", p.Ts) == pytest.approx((BRAKE_BOUNDS[0] * p.Ts, BRAKE_BOUNDS[1] * p.Ts))
    assert BRAKE_BOUNDS[1] > BASE_BOUNDS[1]


def test_exact_base_stands_when_the_base_first_fit_stops_in_a_worse_optimum(monkeypatch):
    """The README's emulator example: exact base, a hidden position friction, 2.5 V for 40 s at 100 Hz,
    angles only.  Freeing the base first (without the friction) puts ktheta at +9 %, and the joint fit with
    the friction stops there at a worse RSS than the friction alone reaches on the nominal base: the base
    then moved +1.4 % together.  Step 5 continues the freed fit from the nested model's optimum."""
    import drillgym.diagnosis.backward as backward
    import drillgym.diagnosis.forward as forward

    fits = []
    real = forward.converged_fit

    def recorded(st, vec, names, max_nfev, refine=True):
        r = real(st, vec, names, max_nfev, refine)
        fits.append((len(names), r.rss_after))
        return r

    monkeypatch.setattr(forward, "converged_fit", recorded)  # the selection's fits
    monkeypatch.setattr(backward, "converged_fit", recorded)  # the nested model of the base decision
    truth = {"pf_c1": 0.135, "pf_s1": 0.21, "pf_c2": 0.0, "pf_s2": 0.0}
    ts = synthetic_measurement(
        "torsional", duration=40.0, rate_hz=100.0, u=2.5, effects=["position_friction"], effect_params=truth
    )
    d = diagnose(ts)
    assert d.selected == ["position_friction"], d.text()
    assert not d.base_off and not d.base_parameters, d.text()
    for name in ("pf_c1", "pf_s1"):
        assert d.effect_values()[name] == pytest.approx(truth[name], rel=0.01)
    # the case it guards: a base-freed fit worse than the nested fit after it, then continued below both
    n_eff = 4
    nested = [i for i, (k, _) in enumerate(fits) if k == n_eff]
    assert nested, fits
    i = nested[0]
    k_joint = max(k for k, _ in fits)  # the base parameters with the friction's
    assert any(k == k_joint and rss > fits[i][1] for k, rss in fits[:i]), fits
    assert fits[i + 1][0] == k_joint and fits[i + 1][1] < fits[i][1], fits


def test_search_composition_is_the_model_when_candidates_are_neutral():
    cands = [LIBRARY[n] for n in ("position_friction", "motor_lag", "string_damping")]
    comp = search_composition(BASE, cands)
    assert comp.effects[0].name == "motor_lag"  # first input: applied exactly to the recorded input
    vals = neutral_values(cands)
    assert vals["tau_m"] == LIBRARY["motor_lag"].parameters[0].lo and vals["pf_c1"] == 0.0 and vals["dtheta"] == 0.0
    comp.vector(RigParams(), vals)  # neutral values are valid values


def test_delay_under_mismatch_is_not_reported_as_a_lag_without_a_tie():
    d = diagnose(recording(RigParams().scaled(**MISMATCH), effects=["input_delay"], delay=0.04))
    assert d.selected in (["input_delay"], ["motor_lag"]), d.text()
    if d.selected == ["motor_lag"]:  # only as a stated tie
        assert "indistinguishable" in d.ranking[0].note, d.text()
    else:
        assert d.effect_values()["delay"] == pytest.approx(0.04, rel=0.25)


def test_lvdt_skew_and_lateral_friction_found_on_anindependent_rig():
    """An independent rig (scipy, smoothed friction: benchmarks/bench_diagnosis_rig.py) leaves the encoders
    several noise units off where the LVDTs fit: with one pooled weight the lateral parameters moved to fit
    the angles and a spurious position friction entered; each sensor weighted by its own misfit, the set
    is right and the skew's value close."""
    rig_recording = independent_rig()

    ts = rig_recording(
        "coupled",
        "ramps",
        12.0,
        200.0,
        5,
        {"lvdt_skew": {"lvdt_skew": 0.035}, "lateral_coulomb": {"Fc_lat": 1.5}},
        {},
        2.6,
        1.5,
    )
    d = diagnose(ts)
    assert sorted(d.selected) == ["lateral_coulomb", "lvdt_skew"], d.text()
    assert d.sensor_misfit and d.sensor_misfit["encoders"] > 1.5, d.text()
    vals = d.effect_values()
    assert vals["lvdt_skew"] == pytest.approx(0.035, rel=0.25) and vals["Fc_lat"] == pytest.approx(1.5, rel=0.1)


def test_prepare_refuses_an_unknown_configuration_in_one_line(capsys):
    from drillgym.cli import main

    with pytest.raises(SystemExit) as e:
        main(["prepare", "--config", "helical"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "helical" in err and "\n" not in err


def test_a_drift_beside_a_brake_asymmetry_is_not_taken_for_a_position_friction():
    """An independent rig (benchmarks/bench_diagnosis_rig.py) with a brake asymmetry and a friction drift,
    30 s of sums of sines at 1 kHz: the search took a position friction (4 harmonics) in the drift's place,
    the split-half check dropped it as not repeating with the angle, and the drift was never screened again
    (brake asymmetry alone reported).  The selection then went on from the remaining set without it; since
    the screens start from the best of a spread of values (:mod:`drillgym.diagnosis.starts`) the drift is
    found directly.  Either way: the true set, the drift's value, no position friction."""
    rig_recording = independent_rig()

    ts = rig_recording(
        "torsional",
        "sum_of_sines",
        30.0,
        1000.0,
        6589,
        {"brake_asymmetry": {"asym_s": 0.367, "asym_c": 0.214}, "friction_drift": {"drift": -0.0041}},
        {},
        0.0,
        3.0,
    )
    d = diagnose(ts)
    assert sorted(d.selected) == ["brake_asymmetry", "friction_drift"], d.text()
    assert d.effect_values()["drift"] == pytest.approx(-0.0041, rel=0.2)
    if "position_friction" in d.skipped:
        assert "both halves" in d.skipped["position_friction"]
        assert set(d.paths["after_halves_check"]) == set(d.selected)


def test_lag_delay_decision_made_on_the_incumbents_base_is_checked():
    """An independent rig with a 25.4 ms motor lag and the identified base parameters, 60 s of a smooth
    quasi-random input at 1 kHz around 2.4 V: the base refit on the comparison grid moved every torque
    parameter about 2.4 % down with the input delay in the model, and with those base parameters for both
    the fine check chose the delay by 338 nats.  The lag with its own base parameters wins (about 500
    nats), so the decision depends on whose base is used: a tie, never a confident delay.  (Since the base
    parameters' prior entered the criterion between search orders, the model kept here was the lag at the
    nominal base, decided for the lag by about 85 nats.  With the base fits converged, the base moves 1-2 %
    and both bases favour the delay while the nominal one favours the lag by about 84 nats: a tie that
    names why.)"""
    rig_recording = independent_rig()

    ts = rig_recording("torsional", "quasi_random", 60.0, 1000.0, 271, {"motor_lag": {"tau_m": 0.0254}}, {}, 2.42, 1.5)
    d = diagnose(ts)
    ld = d.lag_delay
    assert ld is not None and set(d.selected) & {"motor_lag", "input_delay"}, d.text()
    assert ld["chosen"] == "motor_lag" or ld["tie"], ld
    if d.base_off:  # both checks of a decision made on refitted base parameters ran
        assert ld["own_base"] is not None and ld["nominal_base"] is not None, ld
    if ld["chosen"] == "input_delay":  # never a confident delay: the check that reversed it is named
        assert "own base parameters" in ld["doubt"] or "nominal values" in ld["doubt"], ld
        assert "indistinguishable" in next(s.note for s in d.ranking if s.effect == "input_delay"), d.text()
