"""Diagnosis as model selection (issue 13): several effects at once, a base model a few percent
off, effects outside the library written as effect files.

Recordings: drillgym's simulator through the rig's measurement chain (``synthetic_measurement``)
and, for the effect outside the library, an independent scipy model (smoothed friction, Radau;
``tests/test_identification_effects.py``).  The diagnosis is never told what is hidden.
"""

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from drillgym import RigParams
from drillgym.cli import app
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.discovery import Candidate, write_effect_file
from drillgym.diagnosis.selection import neutral_values, search_composition
from drillgym.effects import BASE, LIBRARY, compose
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.io import write_timeseries

from test_identification_effects import scipy_cubic_string

MISMATCH = {"Ts": 1.06, "km": 0.97, "Jl": 1.04}


def _independent_rig():
    """``rig_recording`` of benchmarks/bench_diagnosis_rig.py: recordings made by a simulator other than drillgym's."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_diagnosis_rig import rig_recording

    return rig_recording


def _rec(params=None, effects=None, **values):
    return synthetic_measurement("torsional", params, duration=20.0, rate_hz=250.0, offset=1.0, seed=5,
                                 effects=effects, effect_params=values or None)


def test_two_effects_found_as_a_set():
    d = diagnose(_rec(effects=["position_friction", "motor_lag"], pf_c1=0.12, pf_s1=-0.08, tau_m=0.03))
    assert set(d.selected) == {"position_friction", "motor_lag"}, d.text()
    vals = d.effect_values()
    assert vals["tau_m"] == pytest.approx(0.03, rel=0.2)
    assert vals["pf_c1"] == pytest.approx(0.12, rel=0.2) and vals["pf_s1"] == pytest.approx(-0.08, rel=0.2)
    assert d.rmse_after < 0.1 * d.rmse_before
    assert [s.effect for s in d.ranking[:2]] == d.selected and all(s.significant for s in d.ranking[:2])
    assert not any(s.significant for s in d.ranking[2:])
    assert d.to_json()["lag_delay"] is None  # 250 Hz: too slow for the check at the recording's rate


def test_a_model_that_replaces_a_doubted_effect_by_base_parameters_at_bounds_does_not_replace_it():
    """After the split-half check drops a position friction, the search's replacement is taken unless it puts
    another effect in its place with more base parameters at a bound of their range than the model it
    replaces (it then compensates for the dropped effect, and the model with it is kept, the doubt stated)."""
    from drillgym.diagnosis.ranking import compensates_dropped

    kept = {"selected": ["position_friction", "brake_asymmetry"], "at_bounds": ["Tc"]}
    at_bounds = {"selected": ["brake_asymmetry", "friction_drift"], "at_bounds": ["Tcu", "Ts", "Tc", "ws"]}
    clean = {"selected": ["brake_asymmetry", "friction_drift"], "at_bounds": []}
    assert compensates_dropped(kept, at_bounds) and not compensates_dropped(kept, clean)
    assert not compensates_dropped(kept, {**at_bounds, "at_bounds": ["Ts"]})  # as many as before: taken
    # only left out, nothing in its place: the check's decision stands whatever the bounds
    assert not compensates_dropped({**kept, "selected": kept["selected"] + ["friction_drift"]}, at_bounds)
    assert compensates_dropped({"selected": [], "at_bounds": None}, {"selected": ["motor_lag"], "at_bounds": ["Ts"]})


def test_plain_mismatch_is_not_an_effect_and_moved_parameters_are_named():
    d = diagnose(_rec(RigParams().scaled(**MISMATCH)))
    assert d.selected == [], d.text()
    assert d.base_off
    moved = d.base_parameters
    assert moved and set(moved) & set(MISMATCH), moved
    for name, m in moved.items():  # each entry names nominal, fitted and the change
        assert m["change_pct"] == pytest.approx(100 * (m["fitted"] / m["nominal"] - 1))
    for name in set(moved) & set(MISMATCH):  # the parameters that were off moved the right way
        assert (moved[name]["change_pct"] > 0) == (MISMATCH[name] > 1), moved
    assert "base model is off" in d.text()


def test_effect_found_under_mismatch_with_its_value():
    d = diagnose(_rec(RigParams().scaled(**MISMATCH), effects=["motor_lag"], tau_m=0.03))
    assert d.selected in (["motor_lag"], ["input_delay"]), d.text()
    if d.selected == ["input_delay"]:  # only as a stated tie
        assert "indistinguishable" in d.ranking[0].note
    else:
        assert d.effect_values()["tau_m"] == pytest.approx(0.03, rel=0.25)
    assert d.base_parameters, d.text()


def test_exact_base_stands_when_the_base_first_fit_stops_in_a_worse_optimum(monkeypatch):
    """The README's emulator example: exact base, a hidden position friction, 2.5 V for 40 s at 100 Hz,
    angles only.  Freeing the base first (without the friction) puts ktheta at +9 %, and the joint fit with
    the friction stops there at a worse RSS than the friction alone reaches on the nominal base: the base
    then moved +1.4 % together.  Step 5 continues the freed fit from the nested model's optimum."""
    import drillgym.diagnosis.selection as selection

    fits = []
    real = selection.converged_fit

    def recorded(st, vec, names, max_nfev, refine=True):
        r = real(st, vec, names, max_nfev, refine)
        fits.append((len(names), r.rss_after))
        return r

    monkeypatch.setattr(selection, "converged_fit", recorded)
    truth = {"pf_c1": 0.135, "pf_s1": 0.21, "pf_c2": 0.0, "pf_s2": 0.0}
    ts = synthetic_measurement("torsional", duration=40.0, rate_hz=100.0, u=2.5, effects=["position_friction"],
                               effect_params=truth)
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


def test_candidate_file_is_a_valid_effect(tmp_path):
    cand = Candidate("lower_friction", {"ωl|ωl|": 0.004, "sign(ωl) exp(−|ωl|/1)": -0.01},
                     {"ωl|ωl|": "omega * speed", "sign(ωl) exp(−|ωl|/1)": "direction * math.exp(-speed / 1.0)"},
                     {"ωl|ωl|": 0.0, "sign(ωl) exp(−|ωl|/1)": 1.0}, 0.8, 1000)
    path = write_effect_file(cand, tmp_path / "cand.py")
    comp, values = compose([cand.effect_file])
    assert comp.names == ("candidate_lower_friction",)
    assert values == {"candidate_lower_friction_c1": 0.004, "candidate_lower_friction_c2": -0.01}
    assert "def stick" in path.read_text()
    assert cand.to_json()["dof"] == 2 and "ωl|ωl|" in cand.expression()


def test_cli_outside_the_library_candidate_file_halves_the_error(tmp_path):
    ts = scipy_cubic_string(0.015, duration=14.0, rate_hz=250.0)
    data = write_timeseries(tmp_path / "rec.csv", ts)
    out = tmp_path / "cand.py"
    r = CliRunner().invoke(app, ["diagnose", str(data), "--json", "--candidate-out", str(out)])
    assert r.exit_code == 0, r.output
    js = json.loads(r.output)
    assert js["selected"] == [], js["ranking"]
    assert {"effect", "score", "significant", "fitted"} <= set(js["ranking"][0])
    assert isinstance(js["base_parameters"], dict)
    cand = js["candidate"]
    assert cand is not None and "α³" in cand["expression"] and cand["dof"] >= 1 and cand["explained"] > 0.5
    assert Path(cand["effect_file"].rsplit(":", 1)[0]) == out and out.exists()
    r2 = CliRunner().invoke(app, ["identify", str(data), "--add-effect", cand["effect_file"], "--json",
                                  "--out", str(tmp_path / "p.json")])
    assert r2.exit_code == 0, r2.output
    fit = json.loads(r2.output)
    for c in ("theta_l", "alpha"):  # the user watches the error fall: at least halved
        assert 1 - fit["r2_after"][c] <= 0.5 * (1 - fit["r2_before"][c]), fit


def test_candidate_found_on_the_lower_disc_when_the_upper_disc_is_noise():
    """Free play in the string (a torque −kθ sat(α, g)) seen on the lower disc, the upper disc's residual
    torque dominated by derivative noise: the string group is found with the right sign and size."""
    import numpy as np

    from drillgym.configurations import N_STATE
    from drillgym.diagnosis.discovery import find_candidate
    from drillgym.diagnosis.sparse import ResidualTorque

    rng = np.random.default_rng(3)
    p = RigParams()
    t = np.arange(0, 30.0, 1 / 250)
    wu = 2.0 + 1.5 * np.sin(3.0 * t)
    wl = 2.0 + 1.5 * np.sin(3.0 * t - 0.8)
    S = np.zeros((t.size, N_STATE))
    S[:, 0] = np.cumsum(wu) / 250
    S[:, 1] = np.cumsum(wl) / 250
    S[:, 1] -= np.mean(S[:, 1] - S[:, 0])  # the twist α swings about zero (±0.4 rad), through the free play
    S[:, 2], S[:, 3] = wu, wl
    alpha = S[:, 1] - S[:, 0]
    deficit = -p.ktheta * np.clip(alpha, -0.1, 0.1)  # what the string lacks against kθ α
    tau_l = -deficit
    tau_u = deficit + 0.3 * rng.standard_normal(t.size)
    rt = ResidualTorque(t, tau_u, tau_l, S, np.ones(t.size, bool))
    cand = find_candidate(rt, np.zeros(t.size), p.Ju, p.Jl)
    assert cand is not None and cand.group == "string", cand
    assert cand.explained > 0.5, cand.explained
    sats = [(k, v) for k, v in cand.terms.items() if k.startswith("sat")]
    assert len(sats) == 1, cand.terms
    (label, coef), = sats
    g = float(label.split(",")[1].strip(" )"))
    assert coef < 0 and abs(coef * min(g, 1.0)) == pytest.approx(p.ktheta * 0.1, rel=0.5), cand.terms


def test_measurement_effect_scored_per_channel_is_not_drowned_by_another_channel():
    """An effect that removes a y-only residual (an LVDT skew) while a large, correlated residual stays in
    the angle channel: pooled, the angle channel's variance swamps it; per channel it is clearly found."""
    import numpy as np

    from drillgym.diagnosis.selection import _significant, score
    from drillgym.identification.fitting import FitResult

    rng = np.random.default_rng(0)
    n = 4000
    t = np.arange(n) / 50.0
    angle = 30.0 * np.sin(0.3 * t) + rng.standard_normal(n)  # a slowly varying model error, 30 noise units
    y_small = rng.standard_normal(n)
    y_with_skew = y_small + 2.0 * np.sin(2.0 * t)  # what the skew explains: 2 noise units in y only
    r0 = np.concatenate([angle, y_with_skew])
    r1 = np.concatenate([angle, y_small])
    channels = np.repeat([0, 1], n)
    big = FitResult(["lvdt_skew"], {}, {}, RigParams(), np.zeros(1), float(r0 @ r0), float(r1 @ r1), 2 * n, 1,
                    residual=r1)
    pooled, _ = score(float(r0 @ r0), big, 1)
    per_channel, ne = score(r0, big, 1, channels=channels)
    assert pooled < 15.0 < per_channel  # SIGNIFICANCE is 15 nats
    assert not _significant(per_channel, float(r0 @ r0), float(r1 @ r1), 2 * n)  # pooled RMS cut < 20 %
    assert _significant(per_channel, float(r0 @ r0), float(r1 @ r1), 2 * n, r0, r1, channels)
    nothing = FitResult(["lvdt_skew"], {}, {}, RigParams(), np.zeros(1), float(r0 @ r0), float(r0 @ r0), 2 * n, 1,
                        residual=r0.copy())
    assert score(r0, nothing, 1, channels=channels)[0] < 0  # explaining nothing costs the penalty


def test_objective_channel_ids_follow_the_residual_layout():
    import numpy as np

    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import Objective
    from drillgym.identification.segmented import SegmentedModel

    ts = synthetic_measurement("coupled", duration=6.0, seed=3, offset=2.5)
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    obj = Objective(SegmentedModel([ex], 2.0), {"theta_u": 1.0, "theta_l": 1.0, "x": 1.0, "y": 1.0})
    r = obj.residual_matrix(RigParams().to_vector()[None, :])[0]
    assert obj.channel_ids.shape == r.shape
    assert sorted(set(obj.channel_ids.tolist())) == list(range(len(obj.channels))) and obj.channels == [
        "theta_l", "theta_u", "x", "y"]
    assert np.count_nonzero(np.diff(obj.channel_ids)) == 3  # one experiment: four channels, one block each


def test_split_halves_and_the_agreement_of_a_position_effect():
    import numpy as np

    from drillgym.diagnosis.reproducibility import HalfAgreement, split_halves
    from drillgym.identification.experiment import prepare_experiment

    ex = prepare_experiment(synthetic_measurement("torsional", duration=6.0, seed=1), compare_rate_hz=50.0)
    a, b = split_halves(ex)
    assert a.t[0] == ex.t[0] and b.t[-1] == ex.t[-1] and a.t[-1] == b.t[0]  # they share the middle sample
    assert a.n + b.n == ex.n + 1 and all(len(v) == a.n for v in (*a.meas.values(), *a.rates.values()))
    assert np.array_equal(a.u_value, ex.u_value)  # the input is kept whole (read by absolute time)
    same = HalfAgreement("position_friction", 7.9, {"pf_c1": -0.102, "pf_s1": 0.110},
                         {"pf_c1": -0.102, "pf_s1": 0.104})
    turned = HalfAgreement("position_friction", 1.6, {"pf_c1": -0.004, "pf_s1": 0.014},
                           {"pf_c1": -0.012, "pf_s1": -0.028})
    assert same.agree and not turned.agree
    assert "both halves" in turned.note() and "more revolutions" in turned.note()
    # a half whose fit leaves the parameters where they started (standard errors of about 30: the disc did not
    # slip there) points the same way trivially and cannot confirm the effect (random seed 1313 #14)
    one_half = HalfAgreement("position_friction", 0.0, {"pf_c1": 0.0389, "pf_s1": -0.0092},
                             {"pf_c1": 0.0377, "pf_s1": -0.0068}, {"pf_c1": 0.0044, "pf_s1": 0.0141},
                             {"pf_c1": 28.1, "pf_s1": 44.4})
    assert one_half.cosine > 0.99 and one_half.shown("first") and not one_half.shown("second")
    assert not one_half.agree and "not seen in the second half" in one_half.note()
    seen_twice = HalfAgreement("position_friction", 0.0, one_half.first, one_half.second, one_half.first_std,
                               {"pf_c1": 0.006, "pf_s1": 0.02})
    assert seen_twice.agree
    unknown = HalfAgreement("position_friction", 0.0, one_half.first, one_half.second,
                            {"pf_c1": float("inf"), "pf_s1": float("nan")}, {})
    assert not unknown.shown("first") and unknown.shown("second")  # inf: not seen; no errors at all: not judged


def test_second_half_keeps_the_recordings_clock_for_a_friction_drift():
    """A friction drift counts from the run's start: the second half's model must not restart its clock
    (it did: a real position friction beside a drift was dropped as 'not the same in both halves')."""
    import numpy as np

    from drillgym.diagnosis.reproducibility import split_halves
    from drillgym.diagnosis.selection import selection_model
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import Objective, base_vector, default_scales

    drift = {"drift": -0.008}
    ex = prepare_experiment(_rec(effects=["friction_drift"], **drift), compare_rate_hz=50.0)
    first, second = split_halves(ex)
    assert first.clock_start == 0.0 and second.clock_start == pytest.approx(second.t[0] - ex.t[0])
    from drillgym.diagnosis.effects import effects_for

    cands = effects_for(ex.config)  # the torsional search model (compiled once by `drillgym prepare`)
    comp = search_composition(compose(None)[0], cands)
    vec = base_vector(comp, RigParams(), {**neutral_values(cands), **drift})

    def misfit(part):
        model = selection_model([part], 4.0, comp)
        obj = Objective(model, {"theta_u": 1.0, "theta_l": 1.0}, default_scales([part]))
        model.refine_initial_speeds(vec, obj.weights, obj.scales)
        r = obj.residual_matrix(vec[None, :])[0]
        return float(np.sqrt(np.mean(r * r)))

    m1, m2 = misfit(first), misfit(second)
    assert m2 < 3.0 * max(m1, 1.0), (m1, m2)  # the true model fits both halves (clock restarted: 720 vs 1.4 noise units)


@pytest.mark.parametrize("truth, wrong", [("input_delay", "motor_lag"), ("motor_lag", "input_delay")])
def test_lag_or_delay_is_decided_at_the_recordings_own_rate(truth, wrong):
    from drillgym.diagnosis.ranking import default_segment, default_weights
    from drillgym.diagnosis.timing import decide_lag_delay, decide_lag_delay_many, fine_experiments, fine_rate
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import base_vector

    value = {"input_delay": {"delay": 0.04}, "motor_lag": {"tau_m": 0.04}}
    ts = synthetic_measurement("torsional", duration=15.0, rate_hz=1000.0, signal="steps", offset=1.5, amplitude=2.0,
                               seed=3, effects=[truth], effect_params=value[truth])
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    cands = {n: LIBRARY[n] for n in ("motor_lag", "input_delay")}
    comp = search_composition(BASE, list(cands.values()))
    # both models at the wrong value 40 ms of the other (the search finds each one's own), the wrong one selected
    models = {e: base_vector(comp, RigParams(), {**neutral_values(list(cands.values())), **value[e]}) for e in cands}
    dec = decide_lag_delay([ex], comp, models, wrong, default_weights(ex.config), default_segment(ex.config))
    assert dec is not None and dec.chosen == truth and not dec.tie, dec
    assert dec.values[truth] == pytest.approx(0.04, rel=0.25)
    assert dec.to_json()["chosen"] == truth and dec.to_json()["score_gap_nats"] > 3 and not dec.to_json()["tie"]
    j = dec.to_json()  # the relative difference beside the nats: gap = n_eff ln(RSS ratio)
    assert j["n_eff"] > 10 and j["log_rss_ratio"] > 0
    assert j["log_rss_ratio"] == pytest.approx(dec.gap / dec.n_eff, rel=1e-3, abs=1e-6)
    assert dec.other in dec.tie_note() and "1000 Hz" in dec.tie_note()  # what the ranking states on a tie
    # questions asked together: a search asked twice runs once, and each decision is the one asked alone
    known: dict = {}
    both = decide_lag_delay_many([ex], comp, [(models, wrong), (models, truth)], default_weights(ex.config),
                                 default_segment(ex.config), known=known)
    assert len(known) == 2 and [d.chosen for d in both] == [truth, truth]
    assert both[0].gap == dec.gap and both[0].values == dec.values
    # no finer data than the comparison grid: no decision
    coarse = prepare_experiment(synthetic_measurement("torsional", duration=5.0, rate_hz=50.0, seed=3), compare_rate_hz=50.0)
    assert fine_experiments([coarse]) is None
    slow = synthetic_measurement("torsional", duration=5.0, rate_hz=200.0, seed=3)  # too slow to tell (module doc)
    assert fine_rate(prepare_experiment(slow, compare_rate_hz=50.0)) is None and fine_rate(ex) == 1000.0
    assert decide_lag_delay([coarse], comp, models, wrong, default_weights(ex.config), 4.0) is None
    with pytest.raises(ValueError, match="incumbent"):
        decide_lag_delay([ex], comp, models, "string_damping", default_weights(ex.config), 4.0)


def test_delay_under_mismatch_is_not_reported_as_a_lag_without_a_tie():
    d = diagnose(_rec(RigParams().scaled(**MISMATCH), effects=["input_delay"], delay=0.04))
    assert d.selected in (["input_delay"], ["motor_lag"]), d.text()
    if d.selected == ["motor_lag"]:  # only as a stated tie
        assert "indistinguishable" in d.ranking[0].note, d.text()
    else:
        assert d.effect_values()["delay"] == pytest.approx(0.04, rel=0.25)


def test_each_sensor_is_weighted_by_its_own_misfit():
    """Encoders at 8 noise units (a friction law's systematic error) and LVDTs within the noise: the
    encoders' scales grow 8x, the LVDTs' stay; once balanced, a second call changes nothing; a recording
    of one sensor is never rescaled."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.selection import balance_sensors

    rng = np.random.default_rng(1)
    n = 2000
    channels = ["theta_l", "theta_u", "x", "y"]
    ids = np.repeat(np.arange(4), n)
    noise = {"theta_l": 2e-4, "theta_u": 2e-4, "x": 1e-5, "y": 1e-5}
    obj = SimpleNamespace(channels=channels, channel_ids=ids, scales=dict(noise))
    r = np.concatenate([8.0 * rng.standard_normal(n), 8.0 * rng.standard_normal(n),
                        0.5 * rng.standard_normal(n), 0.5 * rng.standard_normal(n)])
    f = balance_sensors(obj, r, noise)
    assert f["encoders"] == pytest.approx(8.0, rel=0.05) and f["LVDTs"] == 1.0
    assert obj.scales["theta_l"] == pytest.approx(8.0 * noise["theta_l"], rel=0.05)
    assert obj.scales["x"] == noise["x"] and obj.scales["y"] == noise["y"]
    r_balanced = r * np.where(ids < 2, noise["theta_l"] / obj.scales["theta_l"], 1.0)
    assert balance_sensors(obj, r_balanced, noise) == {}
    one = SimpleNamespace(channels=["theta_l", "theta_u"], channel_ids=np.repeat([0, 1], n),
                          scales={"theta_l": 2e-4, "theta_u": 2e-4})
    assert balance_sensors(one, 8.0 * rng.standard_normal(2 * n), {"theta_l": 2e-4, "theta_u": 2e-4}) == {}
    assert one.scales == {"theta_l": 2e-4, "theta_u": 2e-4}


def test_noise_floor_is_in_noise_units_when_sensors_are_weighted():
    """A y residual cut from 1.35 to 1.05 units (one unit = 3 noise units: the LVDTs' misfit) explains
    6.5 noise units², above the floor of 1; read as noise units it would be 0.72, below it."""
    import numpy as np

    from drillgym.diagnosis.selection import _significant

    rng = np.random.default_rng(2)
    n = 3000
    e = rng.standard_normal(n)
    e /= np.sqrt(np.mean(e ** 2))
    r0, r1 = np.concatenate([e, 1.35 * e]), np.concatenate([e, 1.05 * e])
    channels = np.repeat([0, 1], n)
    unit = np.concatenate([np.full(n, 5.0), np.full(n, 3.0)])
    args = (100.0, float(r0 @ r0), float(r1 @ r1), 2 * n, r0, r1, channels)
    assert not _significant(*args)
    assert _significant(*args, unit)


def test_noise_floor_follows_a_residual_already_below_one_noise_unit():
    """The noise unit is a prior (an encoder count / sqrt 12, 10 um on an LVDT).  A model that leaves less
    than one unit shows finer sensors: the floor is then what it leaves.  A coupled recording's motor lag
    (0.86 -> 0.48 units, 92 nats) was refused by the fixed floor of one unit²; a cut that explains less
    than what remains (0.9 -> 0.7) is still refused, and above one unit the floor stays one unit²."""
    import numpy as np

    from drillgym.diagnosis.selection import MIN_EXPLAINED, _significant, noise_floor

    assert noise_floor(0.23) == pytest.approx(0.23) and noise_floor(4.0) == MIN_EXPLAINED
    rng = np.random.default_rng(3)
    n = 4000
    e = rng.standard_normal(n)
    e /= np.sqrt(np.mean(e ** 2))

    def sig(a: float, b: float) -> bool:
        r0, r1 = a * e, b * e
        return _significant(92.0, float(r0 @ r0), float(r1 @ r1), n, r0, r1, np.zeros(n, int))

    assert sig(0.86, 0.48)  # explains 0.51 units², leaves 0.23
    assert not sig(0.9, 0.7)  # explains 0.32, leaves 0.49: within what remains
    assert not sig(1.5, 1.15)  # 23 % cut, explains 0.93 < 1 unit² with more than one unit left
    assert sig(1.5, 1.0)

    def pooled_only(a: float, b: float) -> bool:  # a fit that carries no residual vector: the same floor
        return _significant(92.0, a * a * n, b * b * n, n)

    assert pooled_only(0.86, 0.48) and pooled_only(1.5, 1.0)
    assert not pooled_only(0.9, 0.7) and not pooled_only(1.5, 1.15)


def test_lvdt_skew_and_lateral_friction_found_on_an_independent_rig():
    """An independent rig (scipy, smoothed friction: benchmarks/bench_diagnosis_rig.py) leaves the encoders
    several noise units off where the LVDTs fit: with one pooled weight the lateral parameters moved to fit
    the angles and a spurious position friction entered; each sensor weighted by its own misfit, the set
    is right and the skew's value close."""
    rig_recording = _independent_rig()

    ts = rig_recording("coupled", "ramps", 12.0, 200.0, 5, {"lvdt_skew": {"lvdt_skew": 0.035},
                                                           "lateral_coulomb": {"Fc_lat": 1.5}}, {}, 2.6, 1.5)
    d = diagnose(ts)
    assert sorted(d.selected) == ["lateral_coulomb", "lvdt_skew"], d.text()
    assert d.sensor_misfit and d.sensor_misfit["encoders"] > 1.5, d.text()
    vals = d.effect_values()
    assert vals["lvdt_skew"] == pytest.approx(0.035, rel=0.25) and vals["Fc_lat"] == pytest.approx(1.5, rel=0.1)


def test_lag_delay_decision_under_a_base_at_its_bound_is_a_tie():
    """A 60-nat gap decided with base parameters at the edge of their range is not trusted: stated as a tie
    that names the bound, in the note and in --json."""
    from drillgym.diagnosis.timing import FINE_TIE_NATS, FineDecision

    assert FineDecision("motor_lag", "input_delay", FINE_TIE_NATS - 0.1, 500.0, {"motor_lag": 0.05}).tie
    dec = FineDecision("motor_lag", "input_delay", 59.9, 500.0, {"motor_lag": 0.055, "input_delay": 0.055})
    assert not dec.tie and dec.to_json()["doubt"] == ""
    dec.doubt = "base parameters at a bound of their range (Tc)"
    assert dec.tie and dec.to_json()["tie"]
    note = dec.tie_note()
    assert "59.9 nats, not trusted" in note and "(Tc)" in note and "input_delay" in note


def test_a_parameter_the_data_do_not_depend_on_has_no_finite_standard_error():
    """A motor lag on a constant input changes nothing after the start: its standard error is infinite
    (the pseudo-inverse alone gave 0, printed as 'tau_m=0.3211±0'), with the identifiability warning."""
    import numpy as np

    from drillgym.effects import compose
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import FitVariable, IdentifiabilityWarning, Objective, fit_parameters
    from drillgym.identification.segmented import SegmentedModel

    ts = synthetic_measurement("torsional", duration=6.0, rate_hz=200.0, signal="steps", amplitude=2.5, offset=2.5, seed=1)  # constant 2.5 V
    comp, _ = compose(["motor_lag"], {"tau_m": 0.02})
    ex = prepare_experiment(ts, compare_rate_hz=50.0)
    obj = Objective(SegmentedModel([ex], 2.0, composition=comp), {"theta_u": 1.0, "theta_l": 1.0})
    vec = comp.vector(RigParams(), {"tau_m": 0.02})
    with pytest.warns(IdentifiabilityWarning, match="tau_m"):
        res = fit_parameters(obj, vec, [FitVariable.of_effect(comp, "tau_m", 0.02)], max_nfev=3)
    assert res.std["tau_m"] == np.inf


def test_prepare_refuses_an_unknown_configuration_in_one_line(capsys):
    from drillgym.cli import main

    with pytest.raises(SystemExit) as e:
        main(["prepare", "--config", "helical"])
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "helical" in err and "\n" not in err


def test_shortest_lag_or_delay_told_apart_without_the_fine_check():
    """Below the fine check's rate a lag and a delay shorter than a comparison period plus a recording
    sample are stated as a tie (independent 200 Hz recordings: 17-20 ms ones taken for each other)."""
    from drillgym.diagnosis.timing import resolvable_lag_delay
    from drillgym.identification.experiment import prepare_experiment

    slow = prepare_experiment(synthetic_measurement("torsional", duration=4.0, rate_hz=200.0, seed=1),
                              compare_rate_hz=50.0)
    fast = prepare_experiment(synthetic_measurement("torsional", duration=4.0, rate_hz=1000.0, seed=1),
                              compare_rate_hz=50.0)
    assert resolvable_lag_delay([slow]) == pytest.approx(0.025, rel=1e-3)
    assert resolvable_lag_delay([fast]) == pytest.approx(0.021, rel=1e-3)
    assert resolvable_lag_delay([slow, fast]) == pytest.approx(0.025, rel=1e-3)  # the slowest decides


def test_the_common_torque_scale_is_divided_out_and_a_lag_tried_on_the_rescaled_base_only_when_it_is_off(monkeypatch):
    """The common scale of the torque and inertia parameters (Ju the other way) is removed with their ratios kept;
    the lag is tried again only when that scale is more than 5 % below 1 (a slower upper disc, as a lag makes it)."""
    import numpy as np

    from drillgym.diagnosis.ranking import _lag_from_rescaled_base
    from drillgym.diagnosis.selection import base_free_parameters, torque_scale_removed
    from drillgym.configurations import parse_configuration

    cands = [LIBRARY[n] for n in ("motor_lag", "string_damping")]
    comp = search_composition(BASE, cands)
    nominal = comp.vector(RigParams(), neutral_values(cands))
    names = base_free_parameters(parse_configuration("torsional"))
    scaled = nominal.copy()
    torque = [n for n in ("km", "Tcu", "bu", "ktheta", "Jl", "Ts", "Tc", "bb") if n in names]
    for n, f in zip(torque, (0.98, 0.92, 0.92, 0.945, 0.945, 0.88, 0.945, 0.88)):  # 1515 #14's valley
        scaled[comp.param_index(n)] *= f
    scaled[comp.param_index("ws")] *= 1.05  # a speed, not a torque: kept
    back, g = torque_scale_removed(scaled, nominal, comp, names)
    assert g == pytest.approx(np.exp(np.mean(np.log([0.98, 0.92, 0.92, 0.945, 0.945, 0.88, 0.945, 0.88]))))
    ratio = {n: back[comp.param_index(n)] / nominal[comp.param_index(n)] for n in torque}
    assert np.exp(np.mean(np.log(list(ratio.values())))) == pytest.approx(1.0)
    assert ratio["km"] / ratio["Ts"] == pytest.approx(0.98 / 0.88)  # the ratios to each other kept
    assert back[comp.param_index("ws")] == scaled[comp.param_index("ws")]
    assert torque_scale_removed(scaled, nominal, comp, ())[1] == 1.0  # base held: nothing to divide out

    kept = {"selected": ["string_damping"], "vector": scaled, "base_off": True, "at_bounds": ["Ts", "bb"]}
    call = (None, comp, nominal, cands, names, 2, 4, False)  # returns before any fit in these cases
    assert _lag_from_rescaled_base({**kept, "selected": ["motor_lag"]}, *call) is None  # a lag is in already
    assert _lag_from_rescaled_base({**kept, "base_off": False}, *call) is None
    assert _lag_from_rescaled_base(kept, call[0], comp, nominal, cands[1:], *call[4:]) is None  # no lag candidate
    even = nominal.copy()
    even[comp.param_index("Ts")] *= 0.88  # one parameter at its bound, the common scale 1.6 % off
    assert _lag_from_rescaled_base({**kept, "vector": even}, *call) is None
    faster = nominal.copy()
    for n in torque:
        faster[comp.param_index(n)] *= 1.08  # every torque 8 % high: Ju smaller, the upper disc faster, not a lag
    assert _lag_from_rescaled_base({**kept, "vector": faster}, *call) is None

    # the valley itself (common scale 0.93): the selection runs again from the rescaled base, the lag accepted first
    import drillgym.diagnosis.selection as selection

    seen = {}
    monkeypatch.setattr(selection, "best_effect_start", lambda obj, comp_, vec, effect: vec)
    monkeypatch.setattr(selection, "forward_select", lambda *a, **k: seen.update(k) or {"selected": k["initial"]})
    assert _lag_from_rescaled_base(kept, *call) == {"selected": ["string_damping", "motor_lag"]}
    np.testing.assert_allclose(seen["start"], back)


def test_union_of_the_search_orders_is_tried_only_when_no_order_selected_it(monkeypatch):
    """Two orders each with a stand-in (1616 #15: damping + skew, and damping + lag + anisotropy): the union is
    fitted from the kept model with each missing effect at the values of the order that found it, and the
    backward check runs on all of it.  Orders that agree, or one whose set is the union, start nothing."""
    import numpy as np

    import drillgym.diagnosis.selection as selection
    from drillgym.configurations import parse_configuration
    from drillgym.diagnosis.ranking import _union_of_paths, union_start
    from drillgym.diagnosis.selection import base_free_parameters

    cands = [LIBRARY[n] for n in ("string_damping", "lvdt_skew", "motor_lag", "lateral_anisotropy")]
    comp = search_composition(BASE, cands)
    nominal = comp.vector(RigParams(), neutral_values(cands))
    names = base_free_parameters(parse_configuration("coupled"))

    def model(selected, **values):
        v = nominal.copy()
        for k, x in values.items():
            v[comp.param_index(k)] = x
        return {"selected": selected, "vector": v}

    kept = model(["string_damping", "motor_lag", "lateral_anisotropy"], dtheta=0.007, tau_m=0.03, dk=90.0, b=1.1)
    other = model(["string_damping", "lvdt_skew"], dtheta=0.005, lvdt_skew=0.04)
    got = union_start(kept, [kept, other], comp, cands)
    assert got is not None
    order, start = got
    assert order == ["string_damping", "motor_lag", "lateral_anisotropy", "lvdt_skew"]
    assert start[comp.param_index("lvdt_skew")] == 0.04  # from the order that found it
    assert start[comp.param_index("dtheta")] == 0.007 and start[comp.param_index("tau_m")] == 0.03  # the kept's
    assert start[comp.param_index("dk")] == 90.0 and start[comp.param_index("b")] == 1.1

    assert union_start(kept, [kept, model(["motor_lag"])], comp, cands) is None  # the union is the kept set
    # a delay beside the kept lag is its near-alias, decided by the lag/delay checks: nothing new
    delay = [LIBRARY["input_delay"]]
    comp_d = search_composition(BASE, cands + delay)
    lag_kept = {"selected": ["string_damping", "motor_lag"], "vector": comp_d.vector(RigParams(), neutral_values(cands + delay))}
    with_delay = {**lag_kept, "selected": ["string_damping", "input_delay", "lvdt_skew"]}
    assert union_start(lag_kept, [lag_kept, {**lag_kept, "selected": ["input_delay"]}], comp_d, cands + delay) is None
    assert union_start(lag_kept, [lag_kept, with_delay], comp_d, cands + delay)[0] == [
        "string_damping", "motor_lag", "lvdt_skew"]
    assert union_start(kept, [kept, kept], comp, cands) is None
    # the kept model (the effects-first order, not among the base-freed ones) holds the union: nothing new
    assert union_start(kept, [model(["motor_lag"]), model(["string_damping"])], comp, cands) is None
    assert union_start(model([]), [model([]), model([])], comp, cands) is None  # nothing selected anywhere
    call = (None, comp, nominal, cands, names, 2, 4, False)
    assert _union_of_paths(kept, [kept, other], None, comp, nominal, cands, (), 2, 4, False) is None  # base held

    seen = {}
    monkeypatch.setattr(selection, "forward_select", lambda *a, **k: seen.update(k) or {"selected": k["initial"]})
    assert _union_of_paths(kept, [kept, other], *call)["selected"] == order
    np.testing.assert_allclose(seen["start"], start)
    assert seen["max_effects"] == 4


def test_km_and_bu_moved_alike_are_named_as_a_possible_motor_lag():
    from drillgym.diagnosis.selection import _slow_motor_warning

    def moved(km, bu):
        return {"km": {"nominal": 4.3228, "fitted": 4.3228 * (1 + km / 100), "change_pct": km},
                "bu": {"nominal": 2.4245, "fitted": 2.4245 * (1 + bu / 100), "change_pct": bu}}

    ju = RigParams().Ju
    (w,) = _slow_motor_warning(moved(-10.0, -9.9), ["brake_asymmetry"], ju)  # the independent rig's 33 ms lag
    assert "motor_lag" in w and "22 ms" in w
    assert _slow_motor_warning(moved(-10.0, -9.9), ["motor_lag"], ju) == []  # a lag is already in the model
    assert _slow_motor_warning(moved(-6.0, 5.0), [], ju) == []  # opposite directions: another steady state
    assert _slow_motor_warning(moved(-1.5, -2.0), [], ju) == []  # a few percent: plain mismatch
    assert _slow_motor_warning(moved(6.0, 5.0), [], ju) == []  # faster, not slower


def test_a_ramp_input_is_smooth_and_steps_are_not():
    """Below the fine check's rate a lag/delay decision on a smooth input (ramps: a lag and a delay shift
    the response alike) is stated as a tie; the measure separates the benchmark's input kinds."""
    import numpy as np

    from drillgym.diagnosis.timing import SMOOTH_INPUT_SHARE, input_share_above
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.signals import quasi_random, sum_of_sines

    rng = np.random.default_rng(3)
    t = np.arange(4001) / 200.0
    knots = np.cumsum(np.r_[0.0, rng.uniform(3.0, 8.0, 8)])
    inputs = {"ramps": np.interp(t, knots, 1.0 + 3.0 * rng.uniform(-1, 1, knots.size)),
              "steps": 1.0 + 3.0 * rng.uniform(-1, 1, 10)[np.minimum((t // 2.0).astype(int), 9)],
              "quasi_random": 1.0 + 3.0 * quasi_random(20.0, rate_hz=200.0, seed=3, amplitude=1.0, offset=0.0)[1],
              "sum_of_sines": 1.0 + 3.0 * sum_of_sines(20.0, rate_hz=200.0, seed=3, amplitude=1.0, offset=0.0)[1]}
    p = RigParams()
    corner = p.bu / (2 * np.pi * p.Ju)
    shares = {}
    for kind, u in inputs.items():
        u = np.clip(u[:t.size], -5.0, 5.0)
        ts = synthetic_measurement("torsional", duration=20.0, rate_hz=200.0, input=(t, u), seed=3)
        shares[kind] = input_share_above(prepare_experiment(ts, compare_rate_hz=50.0), corner)
    assert shares["ramps"] < SMOOTH_INPUT_SHARE, shares
    assert min(shares["steps"], shares["quasi_random"], shares["sum_of_sines"]) > 3 * SMOOTH_INPUT_SHARE, shares


def test_a_decisive_lag_delay_check_on_a_smooth_input_is_a_tie_at_any_rate(monkeypatch):
    """What tells a lag from a delay is the response to fast changes of the voltage.  On ramps recorded at
    500 Hz a decisive fine-grid gap (150 nats) is the model's error elsewhere: stated as a tie naming the
    smooth input; the same gap on steps stands."""
    import numpy as np

    import drillgym.diagnosis.timing as timing
    from drillgym.diagnosis.effects import get_effect
    from types import SimpleNamespace

    from drillgym.diagnosis.ranking import _check_lag_delay
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import base_vector

    cands = [get_effect("motor_lag"), get_effect("input_delay")]
    comp = search_composition(compose(None, None)[0], cands)
    nominal = base_vector(comp, RigParams(), neutral_values(cands))
    vec = nominal.copy()
    vec[comp.param_index("tau_m")] = 0.04
    rng = np.random.default_rng(5)
    t = np.arange(10001) / 500.0
    knots = np.cumsum(np.r_[0.0, rng.uniform(3.0, 8.0, 8)])
    inputs = {"ramps": np.interp(t, knots, 1.5 + 2.0 * rng.uniform(-1, 1, knots.size)),
              "steps": 1.5 + 2.0 * rng.uniform(-1, 1, 10)[np.minimum((t // 2.0).astype(int), 9)]}
    monkeypatch.setattr(timing, "decide_lag_delay_many", lambda *a, **k: [timing.FineDecision(
        "motor_lag", "input_delay", 150.0, 500.0, {"motor_lag": 0.04, "input_delay": 0.04}, n_eff=3000.0)])
    for kind, u in inputs.items():
        ts = synthetic_measurement("torsional", duration=20.0, rate_hz=500.0, input=(t, u), seed=3)
        ex = prepare_experiment(ts, compare_rate_hz=50.0)
        out = {"selected": ["motor_lag"], "vector": vec, "ties": {}, "base_off": False, "at_bounds": []}
        dec = _check_lag_delay(out, [ex], comp, SimpleNamespace(weights={}), cands, (), 4.0, nominal)
        assert dec.chosen == "motor_lag" and out["selected"] == ["motor_lag"]
        if kind == "ramps":
            assert dec.tie and "smooth" in dec.doubt and "indistinguishable" in out["ties"]["motor_lag"], dec
        else:
            assert not dec.tie and "motor_lag" not in out["ties"], dec


def test_a_drift_beside_a_brake_asymmetry_is_not_taken_for_a_position_friction():
    """An independent rig (benchmarks/bench_diagnosis_rig.py) with a brake asymmetry and a friction drift,
    30 s of sums of sines at 1 kHz: the search took a position friction (4 harmonics) in the drift's place,
    the split-half check dropped it as not repeating with the angle, and the drift was never screened again
    (brake asymmetry alone reported).  The selection then went on from the remaining set without it; since
    the screens start from the best of a spread of values (:mod:`drillgym.diagnosis.starts`) the drift is
    found directly.  Either way: the true set, the drift's value, no position friction."""
    rig_recording = _independent_rig()

    ts = rig_recording("torsional", "sum_of_sines", 30.0, 1000.0, 6589,
                       {"brake_asymmetry": {"asym_s": 0.367, "asym_c": 0.214}, "friction_drift": {"drift": -0.0041}},
                       {}, 0.0, 3.0)
    d = diagnose(ts)
    assert sorted(d.selected) == ["brake_asymmetry", "friction_drift"], d.text()
    assert d.effect_values()["drift"] == pytest.approx(-0.0041, rel=0.2)
    if "position_friction" in d.skipped:
        assert "both halves" in d.skipped["position_friction"]
        assert set(d.paths["after_halves_check"]) == set(d.selected)


def test_lag_delay_decision_made_on_the_incumbents_base_is_checked():
    """An independent rig with a 25.4 ms motor lag and MODEL.md's base parameters, 60 s of a smooth
    quasi-random input at 1 kHz around 2.4 V: the base refit on the comparison grid moved every torque
    parameter about 2.4 % down with the input delay in the model, and with those base parameters for both
    the fine check chose the delay by 338 nats.  The lag with its own base parameters wins (about 500
    nats), so the decision depends on whose base is used: a tie, never a confident delay.  (Since the base
    parameters' prior entered the criterion between search orders, the model kept here was the lag at the
    nominal base, decided for the lag by about 85 nats.  With the base fits converged, the base moves 1-2 %
    and both bases favour the delay while the nominal one favours the lag by about 84 nats: a tie that
    names why.)"""
    rig_recording = _independent_rig()

    ts = rig_recording("torsional", "quasi_random", 60.0, 1000.0, 271, {"motor_lag": {"tau_m": 0.0254}}, {},
                       2.42, 1.5)
    d = diagnose(ts)
    ld = d.lag_delay
    assert ld is not None and set(d.selected) & {"motor_lag", "input_delay"}, d.text()
    assert ld["chosen"] == "motor_lag" or ld["tie"], ld
    if d.base_off:  # both checks of a decision made on refitted base parameters ran
        assert ld["own_base"] is not None and ld["nominal_base"] is not None, ld
    if ld["chosen"] == "input_delay":  # never a confident delay: the check that reversed it is named
        assert "own base parameters" in ld["doubt"] or "nominal values" in ld["doubt"], ld
        assert "indistinguishable" in next(s.note for s in d.ranking if s.effect == "input_delay"), d.text()


def test_lag_delay_decision_reversed_by_the_nominal_base_is_a_tie():
    """The rule itself: the fine check run again with the base parameters at their nominal values; when it
    decides the other way by 50 nats or more the decision is a tie naming why, by less it stands."""
    from types import SimpleNamespace

    import drillgym.diagnosis.timing as timing
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.ranking import _apply_nominal_check, _nominal_base_models
    from drillgym.diagnosis.selection import neutral_values, search_composition
    from drillgym.effects import compose
    from drillgym.identification.fitting import base_vector

    cands = [get_effect("motor_lag"), get_effect("input_delay")]
    comp = search_composition(compose(None, None)[0], cands)
    nominal = base_vector(comp, RigParams(), neutral_values(cands))
    vec = nominal.copy()
    vec[comp.param_index("km")] *= 0.97
    vec[comp.param_index("delay")] = 0.025
    st = SimpleNamespace(vec=vec, comp=comp, effects={e.name: e for e in cands})
    models = _nominal_base_models(st, "input_delay", ("km",), nominal)
    assert models["input_delay"][comp.param_index("km")] == nominal[comp.param_index("km")]
    assert models["input_delay"][comp.param_index("delay")] == 0.025
    assert models["motor_lag"][comp.param_index("delay")] == 0.0
    assert vec[comp.param_index("km")] != nominal[comp.param_index("km")]  # the selected model is left as it was
    for gap, tie in ((120.0, True), (20.0, False)):
        dec = timing.FineDecision("input_delay", "motor_lag", 300.0, 1000.0, {}, n_eff=1000.0)
        _apply_nominal_check(dec, timing.FineDecision("motor_lag", "input_delay", gap, 1000.0, {}, n_eff=1000.0))
        assert dec.nominal_base["chosen"] == "motor_lag" and dec.nominal_base["score_gap_nats"] == gap
        assert dec.tie is tie and (("nominal values" in dec.doubt) is tie), dec


def test_base_prior_prefers_the_effect_to_a_base_moved_far_when_both_fit_alike():
    """Two base-off selections fitting alike (RSS 4851 and 4888, about 70 effective samples): drift and
    string damping with every torque parameter about 9 % down together (the larger-Ju direction that
    absorbs a motor lag), or the same plus the lag with the base within 3 %.  The information criterion
    alone takes the first (one parameter fewer); with the base parameters' prior (5 % around MODEL.md) the
    lag.  A base moved that far is also beyond the prior's 95 % quantile, a few percent is within it."""
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.ranking import _base_prior, _better, _plausible_prior
    from drillgym.diagnosis.selection import BASE_FREE
    from drillgym.configurations import Configuration
    from drillgym.identification.fitting import base_vector

    cands = [get_effect(n) for n in ("friction_drift", "string_damping", "motor_lag")]
    comp = search_composition(compose(None, None)[0], cands)
    nominal = base_vector(comp, RigParams(), neutral_values(cands))
    base_names = BASE_FREE[Configuration.TORSIONAL]
    far, near = nominal.copy(), nominal.copy()
    for n in base_names:
        far[comp.param_index(n)] *= 0.91
    near[comp.param_index("bb")] *= 1.03
    near[comp.param_index("tau_m")] = 0.029

    def sel(names, rss, vec):
        return {"selected": names, "base_off": True, "at_bounds": [], "rss_final": rss, "fit": None, "n": 70,
                "vector": vec}

    absorbed = sel(["friction_drift", "string_damping"], 4851.0, far)
    lag = sel(["friction_drift", "string_damping", "motor_lag"], 4888.0, near)
    assert _better(absorbed, lag, cands, base_names) is absorbed
    assert _better(absorbed, lag, cands, base_names, comp=comp, nominal=nominal) is lag
    assert _base_prior(absorbed, base_names, comp, nominal) > _plausible_prior(base_names)
    assert _base_prior(lag, base_names, comp, nominal) < 1.0
    # a real fit far better still wins against the prior
    assert _better(sel(["friction_drift", "string_damping"], 3000.0, far), lag, cands, base_names, comp=comp,
                   nominal=nominal)["rss_final"] == 3000.0


def test_a_smooth_input_warns_that_a_lag_or_delay_hides_in_the_motor_side_parameters():
    """On a ramp of slope s a delay d is the voltage offset -s d, which the upper friction takes (an independent
    rig's 23 ms delay on 20 s of ramps at 200 Hz: nothing selected, Tcu -10.9 %): the diagnosis says so when the
    input is smooth, no lag or delay was selected and a motor-side parameter moved; not otherwise."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.ranking import _smooth_input_warning
    from drillgym.effects import compose

    comp = compose(None)[0]
    nominal = comp.vector(None)
    t = np.arange(0.0, 20.0, 0.005)
    ramps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.interp(t, [0, 5, 10, 15, 20], [0, 1, -0.5, 0.8, 0]))
    steps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.sign(np.sin(2 * np.pi * t / 3.0)))
    tcu = {"Tcu": {"nominal": 0.38, "fitted": 0.338, "change_pct": -10.9}}

    warned = _smooth_input_warning([ramps], comp, nominal, {"moved": tcu, "selected": ["friction_drift"]})
    assert len(warned) == 1 and "Tcu -10.9 %" in warned[0] and "voltage steps" in warned[0]
    assert _smooth_input_warning([steps], comp, nominal, {"moved": tcu, "selected": ["friction_drift"]}) == []
    assert _smooth_input_warning([ramps], comp, nominal, {"moved": tcu, "selected": ["input_delay"]}) == []
    assert _smooth_input_warning([ramps], comp, nominal, {"moved": {"Ts": {"change_pct": 5.0}},
                                                          "selected": []}) == []


def test_fits_run_in_parallel_come_back_in_order_with_their_errors():
    """The selection runs a round's independent fits on two threads: results in the jobs' order, a fit's
    ValueError returned in its place (the selection excludes that candidate), other errors raised."""
    import threading
    import time

    from drillgym.diagnosis.selection import _in_parallel

    threads = set()

    def job(i):
        def run():
            threads.add(threading.get_ident())
            time.sleep(0.05 * (3 - i))  # the first job finishes last
            if i == 1:
                raise ValueError("no fit")
            return i * 10
        return run

    out = _in_parallel([job(i) for i in range(3)])
    assert out[0] == 0 and out[2] == 20 and isinstance(out[1], ValueError) and str(out[1]) == "no fit"
    assert len(threads) == 2
    with pytest.raises(ZeroDivisionError):
        _in_parallel([lambda: 1, lambda: 1 / 0])


def test_a_drift_on_less_than_a_revolution_of_sliding_is_a_tie_with_a_position_friction():
    """Over part of a revolution the lower disc's angle moves with time, so a friction that drifts in time and
    one that varies with the angle look alike (an independent rig's position friction reported as a drift,
    the disc sliding through 0.75 rad): a drift selected there is a tie naming the position friction, and the
    reverse; on a disc that slides through several revolutions, or keeps its angle, neither is."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.ranking import _state_time_or_angle_tie, sliding_angle_range

    t = np.linspace(0.0, 30.0, 3001)

    def exp(theta):
        return SimpleNamespace(meas={"theta_l": theta}, rates={"omega_l": np.gradient(theta, t)})

    creeping = exp(np.clip(0.25 * (t - 10.0), 0.0, 0.75))  # stuck, 0.75 rad in 3 s, stuck again
    turning = exp(1.5 * t)  # 45 rad
    stuck = exp(np.full_like(t, 0.3))
    assert sliding_angle_range([creeping]) == pytest.approx(0.75, abs=0.01)
    assert sliding_angle_range([turning]) == pytest.approx(45.0, rel=1e-3)
    assert sliding_angle_range([stuck]) == 0.0
    effects = [LIBRARY[n] for n in ("position_friction", "friction_drift", "string_damping")]
    for selected, tied, other in ((["friction_drift", "string_damping"], "friction_drift", "position_friction"),
                                  (["position_friction"], "position_friction", "friction_drift")):
        out = {"selected": list(selected), "ties": {}}
        _state_time_or_angle_tie(out, [creeping], effects)
        assert list(out["ties"]) == [tied] and other in out["ties"][tied] and "0.75 rad" in out["ties"][tied]
        out = {"selected": list(selected), "ties": {}}
        _state_time_or_angle_tie(out, [turning], effects)
        assert out["ties"] == {}
        out = {"selected": list(selected), "ties": {}}  # a disc that keeps its angle: the angle explains nothing
        _state_time_or_angle_tie(out, [stuck], effects)
        assert out["ties"] == {}
    both = {"selected": ["friction_drift", "position_friction"], "ties": {}}  # both selected: nothing to swap
    _state_time_or_angle_tie(both, [creeping], effects)
    assert both["ties"] == {}


def test_a_measurement_effect_is_screened_with_the_segments_start_speeds_on_its_own_copy_of_the_model():
    """A measurement effect changes the readings the segments restart from (the lateral initial states), and
    through them the torsional prediction; its screen fits the segments' start speeds with it, on a copy of
    the model (the screens run side by side on the shared one, whose speeds stay as they were), and fits
    at least as well as with the speeds held, the skew's value close to the rig's."""
    import numpy as np

    from drillgym.diagnosis.ranking import default_segment, default_weights
    from drillgym.diagnosis.segments import robust_noise
    from drillgym.diagnosis.selection import _best_start, _fit, _State, screen_fit, selection_model
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import Objective, base_vector

    ts = _independent_rig()("coupled", "sum_of_sines", 12.0, 200.0, 5, {"lvdt_skew": {"lvdt_skew": -0.044},
                                                                        "lateral_coulomb": {"Fc_lat": 1.06}}, {}, 2.31, 1.5)
    ex, scales = robust_noise(prepare_experiment(ts, compare_rate_hz=50.0))
    cands = [LIBRARY["lateral_coulomb"], LIBRARY["lvdt_skew"]]
    comp = search_composition(BASE, cands)
    vec = base_vector(comp, RigParams(), {**neutral_values(cands), "Fc_lat": 1.06})
    obj = Objective(selection_model([ex], default_segment(ex.config), comp), default_weights(ex.config), scales)
    obj.model.refine_initial_speeds(vec, obj.weights, obj.scales, fresh=True)
    speeds = obj.model.speeds_snapshot()
    st = _State(obj, comp, vec.copy(), vec.copy(), (), {c.name: c for c in cands})
    screened = screen_fit(st, vec, "lvdt_skew", 8)
    assert all(np.array_equal(a, b) for a, b in zip(obj.model.speeds_snapshot(), speeds))
    held = _fit(st, _best_start(st, vec, "lvdt_skew"), ["lvdt_skew"], 8)
    assert screened.rss_after <= held.rss_after * (1 + 1e-9), (screened.rss_after, held.rss_after)
    assert screened.values["lvdt_skew"] == pytest.approx(-0.044, rel=0.15)
    # a dynamic effect is screened with the speeds held, as before
    coulomb = screen_fit(st, vec, "lateral_coulomb", 4)
    assert "lvdt_skew" not in coulomb.names and all(np.array_equal(a, b) for a, b in zip(obj.model.speeds_snapshot(), speeds))


def test_a_half_whose_disc_slides_less_than_two_revolutions_cannot_refute_a_position_effect():
    """The split-half check drops a position-dependent effect that a half does not show; a half whose lower disc
    slid through less than a revolution can show none (an independent rig's true position friction was dropped
    so, random seed 2020 #6: the first half's disc slid through 1.07 rad), and one between one and two
    revolutions shows it too weakly to refute it (seed 2828 #12: 7.5 rad, the sine term 0.116 ± 0.057 against
    the other half's 0.110 ± 0.002).  Such a half is recognised; a recording turning in both halves is not."""
    import numpy as np

    from drillgym.diagnosis.ranking import _half_cannot_show
    from drillgym.diagnosis.reproducibility import HalfAgreement
    from drillgym.identification.experiment import prepare_experiment

    t = np.arange(4001) / 200.0
    turning_late = prepare_experiment(synthetic_measurement("torsional", duration=20.0, rate_hz=200.0,
                                                            input=(t, np.where(t < 10.0, 0.0, 3.0)), seed=3))
    turning = prepare_experiment(synthetic_measurement("torsional", duration=20.0, rate_hz=200.0,
                                                       input=(t, np.full_like(t, 3.0)), seed=3))
    # the disc starts at 7.5 s: its first half slides through 7.5 rad, between one and two revolutions
    one_turn = prepare_experiment(synthetic_measurement("torsional", duration=20.0, rate_hz=200.0,
                                                        input=(t, np.where(t < 7.5, 0.0, 3.0)), seed=3))

    def check(first_std: float, second_std: float, second: float = 0.1) -> HalfAgreement:
        return HalfAgreement("position_friction", 0.0, {"pf_c1": 0.1}, {"pf_c1": second}, {"pf_c1": first_std},
                             {"pf_c1": second_std})

    unseen_first = check(1.0, 0.01)  # W = 0.01 in the first half: not shown there; shown in the second
    assert not unseen_first.shown("first") and unseen_first.shown("second")
    assert _half_cannot_show([turning_late], [unseen_first])  # the first half kept still: it cannot refute
    assert _half_cannot_show([one_turn], [unseen_first])  # little more than a revolution: it cannot either
    assert not _half_cannot_show([turning], [unseen_first])  # it turned and did not show it: refuted
    assert not _half_cannot_show([turning_late], [check(1.0, 1.0)])  # the second half turned and did not show it
    assert not _half_cannot_show([turning_late], [check(0.01, 0.01, second=-0.1)])  # both show it, disagreeing
    assert not _half_cannot_show([turning_late], [])


def test_an_upper_disc_friction_is_discovered_while_the_lower_disc_is_stuck():
    """Each disc's torque balance holds while that disc slips, whatever the other one does: on an independent
    rig whose lower disc hardly turns (20 s of ramps about 0.83 V, ±3 V), an upper-disc Stribeck bump outside the
    library (0.15 N m, 0.5 rad/s) was missed, the residual torques having been taken only where the lower
    disc slips; it is found on the upper disc's own rows, with its size and speed."""
    import numpy as np

    from drillgym.diagnosis.discovery import discover
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.diagnosis.sparse import residual_torques

    ts = _independent_rig()("torsional", "ramps", 20.0, 500.0, 1979, {"upper_stribeck": {"Tsu": 0.15, "wsu": 0.5}},
                            {}, 0.83, 3.0)
    d = diagnose(ts)
    fine = prepare_experiment(ts, compare_rate_hz=250.0)
    rt = residual_torques(fine, d.vector, effects=d.composition)
    assert np.any(rt.upper_valid & ~rt.lower_valid)  # the upper disc's rows while the lower disc is stuck
    assert np.all(np.isnan(rt.tau_l[~rt.slip])) and np.all(np.isfinite(rt.tau_u[rt.upper_valid]))
    cand, _ = discover(fine, d)
    assert cand is not None and cand.group == "upper_friction", cand
    (label, coef), = [(k, v) for k, v in cand.terms.items() if "ωu/0.5" in k]
    assert coef == pytest.approx(0.15, rel=0.25), cand.terms
