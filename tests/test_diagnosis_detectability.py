"""What a recording's input can show at all: each effect and base parameter's change of the prediction in
noise units, the pairs it shows alike, and the experiment that would show the rest."""

from dataclasses import replace

import numpy as np
import pytest
from test_diagnosis_unexplained import DEAD_ZONE, steps

from drillgym.configurations import Configuration
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.detectability import (
    DETECTABLE_RMS,
    KIND_DEFAULT,
    REVEALED_BY,
    AlikePair,
    Detectability,
    Sensitivity,
    detectability,
    revealed_by,
)
from drillgym.diagnosis.effects import get_effect
from drillgym.diagnosis.results import Diagnosis
from drillgym.diagnosis.screening import screen
from drillgym.diagnosis.state import DiagnosisOptions
from drillgym.effects import Input
from drillgym.identification.synthetic import synthetic_measurement

LAG_DELAY = ["motor_lag", "input_delay"]  # the search composition other diagnosis tests compile


def ramps(duration=12.0):
    """Slow voltage ramps (t, u) on a 1 ms grid."""
    t = np.arange(0.0, duration, 1e-3)
    return t, np.interp(t, [0.0, 4.0, 8.0, 12.0], [0.5, 3.0, 1.0, 2.5])


def shows(ts, **settings):
    return detectability(screen(ts, None, None, DiagnosisOptions(effects=LAG_DELAY, **settings)))


def test_a_slow_ramp_shows_a_lag_and_a_delay_alike_and_steps_at_1khz_tell_them_apart():
    ramp = synthetic_measurement("torsional", duration=12.0, rate_hz=200.0, input=ramps(), seed=3)
    d = shows(ramp)
    by = {s.name: s for s in d.effects}
    assert set(by) == set(LAG_DELAY) and d.rows == 1 + 2 + 2 * len(d.base)  # one batch: nominal, effects, ±base
    assert by["motor_lag"].change_rms > DETECTABLE_RMS  # a 20 ms lag moves the prediction ...
    (pair,) = d.alike  # ... but exactly as a delay does
    assert {pair.first, pair.second} == set(LAG_DELAY) and pair.cosine > 0.999 and pair.apart_rms < DETECTABLE_RMS
    line = pair.line()
    assert "shift this response alike" in line and "1 kHz" in line
    assert any("motor_lag from input_delay" in ln for ln in d.lines())
    assert d.to_json()["alike"][0]["apart_rms"] == pytest.approx(pair.apart_rms)

    step = synthetic_measurement("torsional", duration=8.0, rate_hz=1000.0, input=steps(8.0), seed=3)
    d = shows(step)
    lag = {s.name: s for s in d.effects}["motor_lag"]
    assert lag.detectable and lag.beyond_base > DETECTABLE_RMS and d.alike == (), d.lines()
    assert not any("motor_lag" in ln for ln in d.lines())


def test_a_lower_disc_that_never_moves_cannot_identify_the_brake():
    # 0.1-0.25 V: the upper disc creeps, the string's torque stays below the brake's static level
    ts = synthetic_measurement(
        "torsional", duration=6.0, rate_hz=250.0, input=steps(6.0, (0.15, 0.25, 0.1, 0.2), hold=1.5), seed=3
    )
    assert np.ptp(ts.theta_l) < 0.01
    d = shows(ts)
    base = {s.name: s for s in d.base}
    brake = ("Ts", "Tc", "ws", "delta", "bb")
    assert set(brake) <= set(base)
    for n in brake:
        assert not base[n].detectable and base[n].change_rms < DETECTABLE_RMS
        assert "brake" in base[n].hint
    assert base["km"].detectable and base["Tcu"].detectable  # the motor side still shows
    cannot = [ln for ln in d.lines() if ln.startswith("cannot identify")]
    assert {ln.split()[2] for ln in cannot} >= set(brake)
    js = d.to_json()
    assert js["threshold_rms"] == DETECTABLE_RMS and js["base"]["Ts"]["detectable"] is False


def test_a_users_effect_without_a_hint_gets_its_kinds_default():
    dead_zone = get_effect(DEAD_ZONE)  # examples/effects/motor_dead_zone.py: an Input effect, no revealed_by
    assert dead_zone.kind == "input" and not hasattr(dead_zone, "revealed_by")
    assert revealed_by(dead_zone) == KIND_DEFAULT["input"]

    class Hinted(Input):
        name = "hinted"
        revealed_by = "  a sine sweep   at 2 V "

    assert revealed_by(Hinted) == "a sine sweep at 2 V"
    assert revealed_by(get_effect("motor_lag")) == REVEALED_BY["motor_lag"]
    for kind in ("delay", "input", "force", "friction", "measurement"):
        assert KIND_DEFAULT[kind]


def test_the_diagnosis_says_what_it_cannot_tell_in_text_and_json():
    cannot = Sensitivity("Ts", "base", {"Ts": 0.0139}, 0.0, 0.0, False, "voltages that make the lower disc slip")
    seen = Sensitivity("km", "base", {"km": 0.216}, 90.0, 90.0, True, "steps")
    d = Diagnosis([], Configuration.TORSIONAL, 1.0, {}, 1.0, None, detectability=Detectability((), (cannot, seen), ()))
    text = d.text()
    assert "cannot identify Ts from this recording" in text and "lower disc slip" in text and "km" not in text
    assert d.to_json()["detectability"]["base"]["km"]["change_rms"] == 90.0

    pair = AlikePair("motor_lag", "input_delay", 0.99992, 0.29, "steps at 1 kHz")
    d = replace(d, detectability=Detectability((), (), (pair,)))
    assert "cannot tell motor_lag from input_delay" in d.text()
    decided = {"tie": False, "chosen": "input_delay", "other": "motor_lag", "rate_hz": 1000.0, "score_gap_nats": 40}
    assert "cannot tell motor_lag" not in replace(d, lag_delay=decided).text()  # the fine check decided it
    assert "cannot tell motor_lag" in replace(d, lag_delay={**decided, "tie": True}).text()

    ts = synthetic_measurement("torsional", duration=12.0, rate_hz=200.0, input=ramps(), seed=3)
    d = diagnose(ts, effects=LAG_DELAY, fixed_base=True)  # the pipeline measures it after the screening
    assert d.detectability is not None and d.to_json()["detectability"]["alike"], d.text()
    assert "cannot tell motor_lag from input_delay" in d.text()


def test_an_effect_the_diagnosis_skipped_is_not_said_twice():
    """An effect the diagnosis skipped with its reason (the disc never turns backwards) gets no second "cannot
    tell" line; an undetectable one it tried still does."""
    from drillgym.diagnosis.detectability import Detectability, Sensitivity

    def weak(name):
        return Sensitivity(name, "Friction", {"p": 0.1}, 0.2, 0.2, False, "turn the disc backwards")

    d = Detectability((weak("brake_asymmetry"), weak("friction_drift")), (), ())
    lines = d.lines(said={"brake_asymmetry": "the lower disc hardly turns backwards"})
    assert len(lines) == 1 and "friction_drift" in lines[0] and "brake_asymmetry" not in lines[0]
    assert len(d.lines()) == 2


def test_a_lower_disc_held_against_a_backward_pull_shows_the_brake_asymmetry():
    """A run to 2.7 V then down to −0.1 V leaves the lower disc ahead of the motor by about 5 rad, pulled backwards
    by more than the brake's static level: with a backward static level twice the forward one it holds and never
    turns backwards, and the recording still shows the asymmetry (the backward level decides that it holds); a run
    that stays at 1.5 V, whose disc never rests against such a pull, does not."""
    from drillgym.diagnosis.screening import excitation_missing
    from drillgym.identification.experiment import prepare_experiment

    t = np.arange(0.0, 8.0, 1e-3)
    brake_asymmetry = get_effect("brake_asymmetry")
    said = {}
    for after in (-0.1, 1.5):
        ts = synthetic_measurement(
            "torsional",
            duration=8.0,
            rate_hz=250.0,
            input=(t, np.where(t < 2.0, 2.7, after)),
            seed=3,
            effects=["brake_asymmetry"],
            effect_params={"asym_s": 1.0, "asym_c": 0.2},
        )
        ex = prepare_experiment(ts)
        assert np.mean(ex.rates["omega_l"] < -0.1) < 0.02  # never turns backwards
        said[after] = excitation_missing(brake_asymmetry, [ex])
    assert said[-0.1] == ""
    assert "needs negative rotation" in said[1.5]
