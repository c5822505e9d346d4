"""The command's path to the motor in the residual torques, and motor-side candidates read through it."""

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.diagnosis.discovery import Candidate, dead_zone_variant
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
    assert dead_zone_variant(_candidate({"sat(u, 0.3)": -1.0, "1": -0.1})) is None


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


def test_fits_beside_a_candidate_also_start_from_its_regressed_terms():
    """The candidate's own fit may bend its terms to stand in for a lag it lacks; the fits beside it start once
    from that fit and once from the terms as regressed, the rest of the vector the same."""
    from types import SimpleNamespace

    from drillgym.diagnosis.beside import _starts
    from drillgym.diagnosis.candidate_fit import CandidateFitState
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.motor_terms import MotorVoltageTerms
    from drillgym.effects import Composition

    comp = Composition((get_effect("motor_lag"), MotorVoltageTerms))
    fitted = comp.vector(RigParams(), {"mv_sat": -1.57, "mv_w": 0.24, "tau_m": 0.03})
    reference = SimpleNamespace(vector=fitted)
    state = CandidateFitState(None, comp, reference, ["mv_sat", "mv_w"], (), fitted, (), {"mv_sat": -1.0, "mv_w": 0.37})
    first, second = _starts(state, reference)
    assert np.array_equal(first, fitted)
    i, w = comp.param_index("mv_sat"), comp.param_index("mv_w")
    assert (second[i], second[w]) == (-1.0, 0.37)
    others = np.ones(fitted.size, bool)
    others[[i, w]] = False
    assert np.array_equal(second[others], fitted[others])
    same = CandidateFitState(None, comp, reference, ["mv_sat", "mv_w"], (), fitted, (), {"mv_sat": -1.57, "mv_w": 0.24})
    assert len(_starts(same, reference)) == 1  # a fit that did not move them: one start


@pytest.mark.parametrize(
    ("score", "at_bound", "tie", "better"),
    [(-1.0, False, "input_delay", None), (-40.0, False, None, None), (200.0, True, None, "input_delay")],
)
def test_a_carried_lag_states_a_tie_or_a_better_fit_at_a_bound(monkeypatch, score, at_bound, tie, better):
    """The lag a candidate was found through, with the delay fitted in its place: a tie when the delay scores
    within the tie margin, nothing when far worse, and when far better only with a base parameter at a bound
    of its range, that is said (not a tie, not counted)."""
    from types import SimpleNamespace

    import drillgym.diagnosis.beside as beside
    from drillgym.diagnosis.effects import get_effect
    from drillgym.effects import Composition

    monkeypatch.setattr(beside, "smooth_input_share", lambda *a: (1.0, 1.0))  # steps: fast enough to separate
    comp = Composition((get_effect("motor_lag"),))
    state = SimpleNamespace(composition=comp, result=SimpleNamespace(vector=comp.vector(RigParams(), {"tau_m": 0.03})))
    fit = SimpleNamespace(with_library=("motor_lag",), state=state, values={}, after=None, base_fitted={})
    swap = beside._Trial(get_effect("input_delay"), "motor_lag", score=score, at_bound=at_bound)
    screening = SimpleNamespace(exps=None, model=SimpleNamespace(comp=None, nominal=None))
    out = beside._carried(fit, [swap], {swap.label: score}, screening)
    assert out.selected == "motor_lag" and out.values["tau_m"] == pytest.approx(0.03)
    assert (out.tie_with, out.better_at_bound) == (tie, better)


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


def _fit_recorder(monkeypatch, rss_by_call):
    """``beside``'s fits replaced by a recorder: each call's freed names, and a fit whose RSS is the next one of
    ``rss_by_call``."""
    from types import SimpleNamespace

    import drillgym.diagnosis.beside as beside

    calls = []

    def fake_fit(ctx, vec, names, max_nfev):
        calls.append(list(names))
        rss = rss_by_call[min(len(calls) - 1, len(rss_by_call) - 1)]
        return SimpleNamespace(vector=np.asarray(vec), rss_after=rss, residual=np.full(4, np.sqrt(rss / 4)))

    monkeypatch.setattr(beside, "converged_fit", fake_fit)
    monkeypatch.setattr(beside, "base_at_bounds", lambda ctx, vec: [])
    monkeypatch.setattr(beside, "best_effect_start", lambda obj, comp, vec, effect: vec)
    return calls


def _carried_lag_state():
    """A candidate fitted with the lag it was found through (its tau_m among the fitted names)."""
    from types import SimpleNamespace

    from drillgym.diagnosis.candidate_fit import CandidateFitState
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.motor_terms import MotorVoltageTerms
    from drillgym.diagnosis.search_model import neutral_values
    from drillgym.effects import Composition

    comp = Composition((get_effect("motor_lag"), get_effect("input_delay"), MotorVoltageTerms))
    vec = comp.vector(RigParams(), {"mv_sat": -1.0, "mv_w": 0.4, "tau_m": 0.03})
    result = SimpleNamespace(vector=vec, rss_after=100.0, residual=np.full(4, 5.0))
    state = CandidateFitState(None, comp, result, ["mv_sat", "mv_w", "tau_m"], ("km",), vec)

    def neutralise(v, name):
        out = v.copy()
        for p, value in neutral_values([get_effect(name)]).items():
            out[comp.param_index(p)] = value
        return out

    ctx = SimpleNamespace(obj=SimpleNamespace(channel_ids=None, block_ids=None), vec=vec, neutralise=neutralise)
    state.context = lambda base_names, effects: ctx
    return state, {n: get_effect(n) for n in ("motor_lag", "input_delay")}


def test_a_delay_tried_in_place_of_a_carried_lag_leaves_the_lag_off(monkeypatch):
    """The delay fitted in place of the lag the candidate carries: the lag's time constant is neither freed nor
    left on (a swap that refitted the lag scored 120 nats for a 6 µs delay and was reported as replacing it)."""
    import drillgym.diagnosis.beside as beside
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.search_model import neutral_values

    calls = _fit_recorder(monkeypatch, [90.0])
    state, by_name = _carried_lag_state()
    trial = beside._Trial(get_effect("input_delay"), "motor_lag")
    beside._fit_trial(trial, state, state.result, by_name)
    assert calls and all("tau_m" not in names and "delay" in names for names in calls), calls
    lag_off = neutral_values([get_effect("motor_lag")])["tau_m"]
    assert trial.result.vector[state.composition.param_index("tau_m")] == lag_off  # started (so ended here) off
    added = beside._Trial(get_effect("input_delay"), None)
    calls.clear()
    beside._fit_trial(added, state, state.result, by_name)
    assert all("tau_m" in names for names in calls)  # added beside it, the lag stays fitted


@pytest.mark.parametrize(("rss", "kept"), [(80.0, "refitted"), (120.0, "own")])
def test_trials_are_scored_against_the_candidate_fit_given_the_same_effort(monkeypatch, rss, kept):
    """The reference of the trials beside a candidate is its own fit continued with the trials' free parameters
    (the carried lag's included), taken where it fits better: a trial is credited for its effect, not for the
    evaluations the candidate's own fit did not spend."""
    import drillgym.diagnosis.beside as beside

    calls = _fit_recorder(monkeypatch, [rss])
    state, by_name = _carried_lag_state()
    ref = beside._reference(state, [], by_name)  # nothing the selection took: the carried lag is in the fit
    assert calls and all({"tau_m", "mv_sat", "km"} <= set(names) and "delay" not in names for names in calls)
    assert (ref is state.result) == (kept == "own")
    assert ref.rss_after == min(rss, state.result.rss_after)


@pytest.mark.parametrize(("doubted", "counts"), [(True, True), (False, False)])
def test_a_swap_beside_the_candidate_needs_only_the_tie_margin_when_the_selection_could_not_tell(
    monkeypatch, doubted, counts
):
    """In place of an effect the selection took, a trial 6 nats better counts only when the selection had said it
    could not tell that effect from another (a stated lag/delay tie): then the incumbent has no precedence, and
    the tie margin (3 nats) decides; otherwise the selection's significance (15 nats) does."""
    import drillgym.diagnosis.beside as beside
    from drillgym.diagnosis.effects import get_effect

    _fit_recorder(monkeypatch, [90.0])
    monkeypatch.setattr(beside, "score", lambda r0, res, k, channels=None, blocks=None: (6.0, None))
    state, by_name = _carried_lag_state()
    trial = beside._Trial(get_effect("motor_lag"), "input_delay", doubted)
    beside._fit_trial(trial, state, state.result, by_name)
    assert trial.counts is counts


@pytest.mark.parametrize(
    ("scores", "said"),
    [({"motor_lag": 23.8, "input_delay": 23.1}, True), ({"motor_lag": -5.9, "input_delay": -5.9}, False),
     ({"motor_lag": 23.8, "input_delay": 12.0}, False)],
)  # fmt: skip
def test_a_lag_and_a_delay_that_help_alike_but_do_not_count_are_said_to_be_possible(scores, said):
    """Beside the candidate neither counts, but both improve the fit by more than the tie margin and alike (free
    play at the motor after a lag, quasi-random input: +23.8 and +23.1 nats): the line says one of them may be
    there and which experiment tells them apart, instead of only listing the scores."""
    from drillgym.diagnosis.beside import BesideCandidate

    line = BesideCandidate(None, scores=scores).line()
    assert line.startswith("  beside it, no library effect of the signal path counts")
    assert ("one of them may be there" in line) is said


def test_a_trial_held_back_only_by_a_bound_is_said_when_none_counts():
    """A lag 630 nats better beside a dead zone whose form is off (500 Hz, quasi-random input), not counted because a
    base parameter ends at a bound: the line says so instead of only listing the scores."""
    from drillgym.diagnosis.beside import BesideCandidate

    held = BesideCandidate(None, scores={"motor_lag": 629.6, "input_delay": 310.3}, better_at_bound="motor_lag")
    assert "motor_lag fits far better but only with a base parameter at a bound" in held.line()
    assert "at a bound" not in BesideCandidate(None, scores={"motor_lag": 629.6}).line()
