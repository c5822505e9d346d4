"""The motor encoder's reading as a candidate: free play between the motor's shaft and the upper disc, which the
residual torques cannot show, found by its own fit and written as a Measurement effect file."""

import math

import numpy as np
import pytest

from drillgym import RigParams
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.effect_file import write_effect_file
from drillgym.diagnosis.motor_terms import ENCODER_TERM, EncoderTerms
from drillgym.diagnosis.results import Candidate
from drillgym.diagnosis.sensor_reading import reading_candidates
from drillgym.effects import Measurement, Parameter, compose
from drillgym.identification.synthetic import synthetic_measurement


class ShaftPlay(Measurement):
    """The test's own backlash (not the candidate's form: a hard sign, no smoothing)."""

    name = "shaft_play_for_test"
    channels = ("theta_u",)
    parameters = (Parameter("gap", "rad", -0.1, 0.1, 0.0, 1e-3, "half the play", neutral=0.0),)

    def measure(theta_u, omega_u, gap):
        return theta_u + gap * (1.0 if omega_u > 0.0 else (-1.0 if omega_u < 0.0 else 0.0))


def _encoder_candidate(play: float, width: float) -> Candidate:
    return Candidate(
        "motor_encoder", {ENCODER_TERM: play}, {ENCODER_TERM: "math.tanh(omega_u / U0)"}, {ENCODER_TERM: 0.0}, 0.9, 0,
        widths={ENCODER_TERM: width}, reach={ENCODER_TERM: 0.05},
    )  # fmt: skip


def test_the_reading_candidate_is_written_as_a_measurement_of_theta_u(tmp_path):
    cand = _encoder_candidate(0.021, 0.07)
    path = write_effect_file(cand, tmp_path / "cand.py", "shaft_play")
    comp, _ = compose([cand.effect_file])
    effect = comp.effects[0]
    assert issubclass(effect, Measurement) and effect.channels == ("theta_u",)
    assert path.read_text(encoding="utf-8").startswith('"""Candidate effect written by `drillgym diagnose')
    vals = {"shaft_play_c1": 0.021, "shaft_play_w1": 0.07}
    p = comp.vector(RigParams(), vals)
    theta, omega = np.array([1.0, 2.0, 3.0]), np.array([-0.5, 0.01, 2.0])
    zeros = np.zeros(3)
    tu, tl, _, _ = comp.measure(theta, zeros, zeros, zeros, p, omega, zeros)
    np.testing.assert_allclose(tu, theta + 0.021 * np.tanh(omega / 0.07), rtol=0, atol=1e-15)
    assert "motor encoder reading = θu +0.021·tanh(ωu/w), w = 0.07 rad/s  [rad]" == cand.expression()
    assert cand.found_line().startswith("candidate outside the library (what the motor encoder reads, by its own fit")


def test_the_terms_effect_reads_the_same_as_a_written_file():
    comp, vals = compose([EncoderTerms], {"me_play": 0.03, "me_w": 0.2})
    p = comp.vector(RigParams(), vals)
    omega = np.linspace(-1.0, 1.0, 7)
    tu = comp.measure(np.zeros(7), np.zeros(7), np.zeros(7), np.zeros(7), p, omega, np.zeros(7))[0]
    np.testing.assert_allclose(tu, 0.03 * np.tanh(omega / 0.2), rtol=0, atol=1e-15)


@pytest.mark.slow
def test_free_play_at_the_motor_encoder_is_found_by_its_own_fit(tmp_path):
    """10 s of steps that reverse the upper disc, read through a 0.025 rad play (a hard sign, not the candidate's
    tanh): the library explains nothing; the reading candidate is kept, its play found within 5 %, nearly all of
    the unexplained variance removed, and the file it is written to fits like the candidate."""
    ts = synthetic_measurement(
        "torsional", None, duration=10.0, rate_hz=250.0, signal="steps", offset=0.0, amplitude=2.5, seed=3,
        effects=[ShaftPlay], effect_params={"gap": 0.025},
    )  # fmt: skip
    out = tmp_path / "cand.py"
    d = diagnose(ts, discover=True, candidate_out=out)
    assert d.unexplained is not None and not d.unexplained.explained  # the play is well above the noise
    c = d.candidate
    assert c is not None and c.group == "motor_encoder"
    assert c.fit.variance_cut > 0.9
    play = c.fit.values[c.fit.file_name("me_play")]  # the play term, beside the scale and the offset
    assert play == pytest.approx(0.025, rel=0.05)
    assert math.isclose(c.terms[ENCODER_TERM], play)
    assert not d.advice  # a candidate kept: no advice that nothing explains the residual
    comp, _ = compose([c.effect_file])
    assert issubclass(comp.effects[0], Measurement)
    assert reading_candidates(d)  # the diagnosis' own residual (before the candidate) is not at the noise


class _Fit:
    """What choose_candidate reads of a fit."""

    def __init__(self, cut: float):
        self.variance_cut = cut
        self.values = {"me_play": 0.01, "me_w": 0.05}
        self.after = type("After", (), {"explained": False})()
        self.state = None  # where the fit ended (the base parameters fitted with it)


@pytest.mark.parametrize(
    ("discovered_cut", "reading_cut", "kept"),
    [
        (0.05, 0.2, "discovered"),
        (0.05, 0.4, "reading"),
        (0.6, 0.5, "discovered"),
        (None, 0.2, None),
        (None, 0.35, "reading"),
    ],
)
def test_the_reading_is_kept_when_its_fit_removes_more_and_at_least_the_bar(
    monkeypatch, discovered_cut, reading_cut, kept
):
    """The reading replaces the discovered candidate only when its own fit removes more of the unexplained
    variance and at least MIN_READING_CUT (0.3) of it; with none discovered, the bar alone decides."""
    from drillgym.diagnosis import candidate_fit

    discovered = None
    if discovered_cut is not None:
        discovered = _encoder_candidate(0.0, 0.05)
        discovered.group = "upper_force"
        discovered.fit = _Fit(discovered_cut)
    monkeypatch.setattr(candidate_fit, "_discovered", lambda s, d, c, n: (c, None))
    monkeypatch.setattr(candidate_fit, "fit_candidate", lambda s, d, c, n: _Fit(reading_cut))
    monkeypatch.setattr(candidate_fit, "_screen_cut", lambda s, d, c, n: reading_cut)  # every one passes its screen
    diagnosis = type("D", (), {"candidate": discovered})()
    reading = _encoder_candidate(0.005, 0.05)
    got = candidate_fit.choose_candidate(None, diagnosis, {}, None, [reading])
    if kept is None:
        assert got is None
    else:
        assert got is (reading if kept == "reading" else discovered)
        other = discovered if kept == "reading" else reading
        assert got.alternative is other


def test_a_reading_is_fitted_in_full_only_when_its_screen_removes_enough(monkeypatch):
    """Of two readings, the one whose screen removes less than SCREEN_CUT is never fitted with the base parameters
    freed, nor offered as the alternative; with every screen below it no reading is fitted at all."""
    from drillgym.diagnosis import candidate_fit

    discovered = _encoder_candidate(0.0, 0.05)
    discovered.group = "upper_force"
    discovered.fit = _Fit(0.05)
    screens = {"motor": candidate_fit.SCREEN_CUT / 2, "lower": 2 * candidate_fit.SCREEN_CUT}
    fitted = []
    motor, lower = _encoder_candidate(0.005, 0.05), _encoder_candidate(0.005, 0.05)
    names = {id(motor): "motor", id(lower): "lower"}
    monkeypatch.setattr(candidate_fit, "_discovered", lambda s, d, c, n: (c, None))
    monkeypatch.setattr(candidate_fit, "_screen_cut", lambda s, d, c, n: screens[names[id(c)]])
    monkeypatch.setattr(candidate_fit, "fit_candidate", lambda s, d, c, n: fitted.append(names[id(c)]) or _Fit(0.5))
    diagnosis = type("D", (), {"candidate": discovered})()
    got = candidate_fit.choose_candidate(None, diagnosis, {}, None, [motor, lower])
    assert fitted == ["lower"] and got is lower and got.alternative is discovered
    screens["lower"] = 0.0
    fitted.clear()
    discovered.alternative = None
    got = candidate_fit.choose_candidate(None, diagnosis, {}, None, [motor, lower])
    assert fitted == [] and got is discovered and got.alternative is None
