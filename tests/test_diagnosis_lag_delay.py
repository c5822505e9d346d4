"""A motor lag or an input delay: decided at the recording's own rate, and stated as a tie when the data
cannot tell them apart."""

import pytest

from drillgym import RigParams
from drillgym.diagnosis.results import BaseChange, Selection
from drillgym.diagnosis.search_model import neutral_values, search_composition
from drillgym.effects import BASE, LIBRARY, compose
from drillgym.identification.synthetic import synthetic_measurement


@pytest.mark.parametrize("truth, wrong", [("input_delay", "motor_lag"), ("motor_lag", "input_delay")])
def test_lag_or_delay_is_decided_at_the_recordings_own_rate(truth, wrong):
    from drillgym.diagnosis.screening import default_segment, default_weights
    from drillgym.diagnosis.timing import decide_lag_delay, decide_lag_delay_many, fine_experiments, fine_rate
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import base_vector

    value = {"input_delay": {"delay": 0.04}, "motor_lag": {"tau_m": 0.04}}
    ts = synthetic_measurement(
        "torsional",
        duration=15.0,
        rate_hz=1000.0,
        signal="steps",
        offset=1.5,
        amplitude=2.0,
        seed=3,
        effects=[truth],
        effect_params=value[truth],
    )
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
    both = decide_lag_delay_many(
        [ex],
        comp,
        [(models, wrong), (models, truth)],
        default_weights(ex.config),
        default_segment(ex.config),
        known=known,
    )
    assert len(known) == 2 and [d.chosen for d in both] == [truth, truth]
    assert both[0].gap == dec.gap and both[0].values == dec.values
    # no finer data than the comparison grid: no decision
    coarse = prepare_experiment(
        synthetic_measurement("torsional", duration=5.0, rate_hz=50.0, seed=3), compare_rate_hz=50.0
    )
    assert fine_experiments([coarse]) is None
    slow = synthetic_measurement("torsional", duration=5.0, rate_hz=200.0, seed=3)  # too slow to tell (module doc)
    assert fine_rate(prepare_experiment(slow, compare_rate_hz=50.0)) is None and fine_rate(ex) == 1000.0
    assert decide_lag_delay([coarse], comp, models, wrong, default_weights(ex.config), 4.0) is None
    with pytest.raises(ValueError, match="incumbent"):
        decide_lag_delay([ex], comp, models, "string_damping", default_weights(ex.config), 4.0)


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


def test_shortest_lag_or_delay_told_apart_without_the_fine_check():
    """Below the fine check's rate a lag and a delay shorter than a comparison period plus a recording
    sample are stated as a tie (independent 200 Hz recordings: 17-20 ms ones taken for each other)."""
    from drillgym.diagnosis.timing import resolvable_lag_delay
    from drillgym.identification.experiment import prepare_experiment

    slow = prepare_experiment(
        synthetic_measurement("torsional", duration=4.0, rate_hz=200.0, seed=1), compare_rate_hz=50.0
    )
    fast = prepare_experiment(
        synthetic_measurement("torsional", duration=4.0, rate_hz=1000.0, seed=1), compare_rate_hz=50.0
    )
    assert resolvable_lag_delay([slow]) == pytest.approx(0.025, rel=1e-3)
    assert resolvable_lag_delay([fast]) == pytest.approx(0.021, rel=1e-3)
    assert resolvable_lag_delay([slow, fast]) == pytest.approx(0.025, rel=1e-3)  # the slowest decides


def test_km_and_bu_moved_alike_are_named_as_a_possible_motor_lag():
    from drillgym.diagnosis.backward import slow_motor_warning

    def moved(km, bu):
        return {
            "km": BaseChange(4.3228, 4.3228 * (1 + km / 100), km, float("nan")),
            "bu": BaseChange(2.4245, 2.4245 * (1 + bu / 100), bu, float("nan")),
        }

    ju = RigParams().Ju
    (w,) = slow_motor_warning(moved(-10.0, -9.9), ["brake_asymmetry"], ju)  # the independent rig's 33 ms lag
    assert "motor_lag" in w and "22 ms" in w
    assert slow_motor_warning(moved(-10.0, -9.9), ["motor_lag"], ju) == []  # a lag is already in the model
    assert slow_motor_warning(moved(-6.0, 5.0), [], ju) == []  # opposite directions: another steady state
    assert slow_motor_warning(moved(-1.5, -2.0), [], ju) == []  # a few percent: plain mismatch
    assert slow_motor_warning(moved(6.0, 5.0), [], ju) == []  # faster, not slower


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
    inputs = {
        "ramps": np.interp(t, knots, 1.0 + 3.0 * rng.uniform(-1, 1, knots.size)),
        "steps": 1.0 + 3.0 * rng.uniform(-1, 1, 10)[np.minimum((t // 2.0).astype(int), 9)],
        "quasi_random": 1.0 + 3.0 * quasi_random(20.0, rate_hz=200.0, seed=3, amplitude=1.0, offset=0.0)[1],
        "sum_of_sines": 1.0 + 3.0 * sum_of_sines(20.0, rate_hz=200.0, seed=3, amplitude=1.0, offset=0.0)[1],
    }
    p = RigParams()
    corner = p.bu / (2 * np.pi * p.Ju)
    shares = {}
    for kind, u in inputs.items():
        u = np.clip(u[: t.size], -5.0, 5.0)
        ts = synthetic_measurement("torsional", duration=20.0, rate_hz=200.0, input=(t, u), seed=3)
        shares[kind] = input_share_above(prepare_experiment(ts, compare_rate_hz=50.0), corner)
    assert shares["ramps"] < SMOOTH_INPUT_SHARE, shares
    assert min(shares["steps"], shares["quasi_random"], shares["sum_of_sines"]) > 3 * SMOOTH_INPUT_SHARE, shares


def test_a_decisive_lag_delay_check_on_a_smooth_input_is_a_tie_at_any_rate(monkeypatch):
    """What tells a lag from a delay is the response to fast changes of the voltage.  On ramps recorded at
    500 Hz a decisive fine-grid gap (150 nats) is the model's error elsewhere: stated as a tie naming the
    smooth input; the same gap on steps stands."""
    from types import SimpleNamespace

    import numpy as np

    import drillgym.diagnosis.timing as timing
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.lag_delay import check_lag_delay
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
    inputs = {
        "ramps": np.interp(t, knots, 1.5 + 2.0 * rng.uniform(-1, 1, knots.size)),
        "steps": 1.5 + 2.0 * rng.uniform(-1, 1, 10)[np.minimum((t // 2.0).astype(int), 9)],
    }
    monkeypatch.setattr(
        timing,
        "decide_lag_delay_many",
        lambda *a, **k: [
            timing.FineDecision(
                "motor_lag", "input_delay", 150.0, 500.0, {"motor_lag": 0.04, "input_delay": 0.04}, n_eff=3000.0
            )
        ],
    )
    for kind, u in inputs.items():
        ts = synthetic_measurement("torsional", duration=20.0, rate_hz=500.0, input=(t, u), seed=3)
        ex = prepare_experiment(ts, compare_rate_hz=50.0)
        out = Selection(selected=["motor_lag"], vector=vec)
        search = SimpleNamespace(
            obj=SimpleNamespace(weights={}), comp=comp, candidates=cands, base_names=(), nominal=nominal
        )
        dec = check_lag_delay(out, [ex], search, 4.0)
        assert dec.chosen == "motor_lag" and out.selected == ["motor_lag"]
        if kind == "ramps":
            assert dec.tie and "smooth" in dec.doubt and "indistinguishable" in out.ties["motor_lag"], dec
        else:
            assert not dec.tie and "motor_lag" not in out.ties, dec


def test_lag_delay_decision_reversed_by_the_nominal_base_is_a_tie():
    """The rule itself: the fine check run again with the base parameters at their nominal values; when it
    decides the other way by 50 nats or more the decision is a tie naming why, by less it stands."""
    import drillgym.diagnosis.timing as timing
    from drillgym.diagnosis.context import SelectionContext
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.lag_delay import apply_nominal_check, nominal_base_models
    from drillgym.effects import compose
    from drillgym.identification.fitting import base_vector

    cands = [get_effect("motor_lag"), get_effect("input_delay")]
    comp = search_composition(compose(None, None)[0], cands)
    nominal = base_vector(comp, RigParams(), neutral_values(cands))
    vec = nominal.copy()
    vec[comp.param_index("km")] *= 0.97
    vec[comp.param_index("delay")] = 0.025
    ctx = SelectionContext(None, comp, vec, nominal, ("km",), {e.name: e for e in cands})
    models = nominal_base_models(ctx, "input_delay")
    assert models["input_delay"][comp.param_index("km")] == nominal[comp.param_index("km")]
    assert models["input_delay"][comp.param_index("delay")] == 0.025
    assert models["motor_lag"][comp.param_index("delay")] == 0.0
    assert vec[comp.param_index("km")] != nominal[comp.param_index("km")]  # the selected model is left as it was
    for gap, tie in ((120.0, True), (20.0, False)):
        dec = timing.FineDecision("input_delay", "motor_lag", 300.0, 1000.0, {}, n_eff=1000.0)
        apply_nominal_check(dec, timing.FineDecision("motor_lag", "input_delay", gap, 1000.0, {}, n_eff=1000.0))
        assert dec.nominal_base["chosen"] == "motor_lag" and dec.nominal_base["score_gap_nats"] == gap
        assert dec.tie is tie and (("nominal values" in dec.doubt) is tie), dec


def test_a_smooth_input_warns_that_a_lag_or_delay_hides_in_the_motor_side_parameters():
    """On a ramp of slope s a delay d is the voltage offset -s d, which the upper friction takes (an independent
    rig's 23 ms delay on 20 s of ramps at 200 Hz: nothing selected, Tcu -10.9 %): the diagnosis says so when the
    input is smooth, no lag or delay was selected and a motor-side parameter moved; not otherwise."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.lag_delay import smooth_input_warning
    from drillgym.effects import compose

    comp = compose(None)[0]
    nominal = comp.vector(None)
    t = np.arange(0.0, 20.0, 0.005)
    ramps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.interp(t, [0, 5, 10, 15, 20], [0, 1, -0.5, 0.8, 0]))
    steps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.sign(np.sin(2 * np.pi * t / 3.0)))
    tcu = {"Tcu": BaseChange(0.38, 0.338, -10.9, float("nan"))}

    warned = smooth_input_warning([ramps], comp, nominal, tcu, ["friction_drift"])
    assert len(warned) == 1 and "Tcu -10.9 %" in warned[0] and "voltage steps" in warned[0]
    assert smooth_input_warning([steps], comp, nominal, tcu, ["friction_drift"]) == []
    assert smooth_input_warning([ramps], comp, nominal, tcu, ["input_delay"]) == []
    assert smooth_input_warning([ramps], comp, nominal, {"Ts": BaseChange(1.0, 1.05, 5.0, float("nan"))}, []) == []


def test_a_decision_the_other_ones_own_base_reverses_takes_the_other_one(monkeypatch):
    """Decided on base parameters refitted with the incumbent (a delay by 2236 nats), reversed with the other
    one's own base parameters (a lag by 310): each fitted with its own base is the fair comparison, and where it
    reversed the decision the incumbent was the wrong one on every independent recording seen, so the lag is
    taken, with its own base as the start of its refit, and the tie stated with both figures."""
    from types import SimpleNamespace

    import numpy as np

    import drillgym.diagnosis.lag_delay as lag_delay
    import drillgym.diagnosis.timing as timing
    from drillgym.diagnosis.effects import get_effect
    from drillgym.identification.experiment import prepare_experiment
    from drillgym.identification.fitting import base_vector

    cands = [get_effect("motor_lag"), get_effect("input_delay")]
    comp = search_composition(compose(None, None)[0], cands)
    nominal = base_vector(comp, RigParams(), neutral_values(cands))
    vec = nominal.copy()
    vec[comp.param_index("delay")] = 0.015
    own = nominal.copy()
    own[comp.param_index("tau_m")] = 0.016
    t = np.arange(10001) / 500.0
    u = 1.5 + 2.0 * np.random.default_rng(5).uniform(-1, 1, 10)[np.minimum((t // 2.0).astype(int), 9)]
    ex = prepare_experiment(synthetic_measurement("torsional", duration=20.0, input=(t, u), seed=3), compare_rate_hz=50)
    values = {"motor_lag": 0.0167, "input_delay": 0.0151}
    held_base = timing.FineDecision("input_delay", "motor_lag", 2236.0, 500.0, values, n_eff=10000.0)
    reversed_ = timing.FineDecision("motor_lag", "input_delay", 310.0, 500.0, values, n_eff=10000.0)
    nominal_check = timing.FineDecision("motor_lag", "input_delay", 40.0, 500.0, values, n_eff=10000.0)
    answers = iter([[held_base], [reversed_, nominal_check]])
    monkeypatch.setattr(timing, "decide_lag_delay_many", lambda *a, **k: next(answers))
    monkeypatch.setattr(lag_delay, "own_base", lambda *a: own)
    taken = []
    monkeypatch.setattr(
        lag_delay, "_take_other", lambda out, ctx, a, b, model_b, value: taken.append((a, b, model_b, value))
    )
    out = Selection(selected=["input_delay"], vector=vec, base_off=True)
    search = SimpleNamespace(
        obj=SimpleNamespace(weights={}), comp=comp, candidates=cands, base_names=("km",), nominal=nominal
    )
    dec = lag_delay.check_lag_delay(out, [ex], search, 4.0)
    assert dec.chosen == "motor_lag" and dec.tie, dec
    assert "2236" in dec.doubt and "310" in dec.doubt and "own base parameters" in dec.doubt
    assert dec.own_base["chosen"] == "input_delay" and dec.nominal_base["chosen"] == "motor_lag"
    assert len(taken) == 1 and taken[0][:2] == ("input_delay", "motor_lag") and taken[0][2] is own
    assert taken[0][3] == 0.0167
    assert "indistinguishable" in out.ties["motor_lag"]


def test_a_lag_the_model_holds_undecided_on_a_smooth_input_is_stated():
    """A lag held in the model (the one a candidate's terms were found through, refitted when the library is
    selected again) is never weighed against a delay by the check: on ramps the diagnosis says either may be
    there; on steps, or with both held, nothing."""
    from types import SimpleNamespace

    import numpy as np

    from drillgym.diagnosis.lag_delay import held_timing_warning
    from drillgym.effects import compose

    comp = compose(["motor_lag"])[0]
    nominal = comp.vector(None)
    t = np.arange(0.0, 20.0, 0.005)
    ramps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.interp(t, [0, 5, 10, 15, 20], [0, 1, -0.5, 0.8, 0]))
    steps = SimpleNamespace(u_time=t, u_value=1.3 + 1.5 * np.sign(np.sin(2 * np.pi * t / 3.0)))

    warned = held_timing_warning([ramps], comp, nominal, ["motor_lag", "candidate_motor_voltage"])
    assert len(warned) == 1 and warned[0].startswith("motor_lag is held") and "input_delay" in warned[0]
    assert "voltage steps" in warned[0]
    assert held_timing_warning([steps], comp, nominal, ["motor_lag"]) == []
    assert held_timing_warning([ramps], comp, nominal, ["motor_lag", "input_delay"]) == []
    assert held_timing_warning([ramps], comp, nominal, ["position_friction"]) == []
