"""A kept voltage candidate read the other way: a dead zone for an offset, an offset for a dead zone."""

from dataclasses import replace

import pytest

from drillgym.diagnosis.candidate import Candidate
from drillgym.diagnosis.discovery_terms import _voltage_terms
from drillgym.diagnosis.effect_file import write_effect_file
from drillgym.diagnosis.effects import get_effect
from drillgym.diagnosis.motor_terms import MotorVoltageTerms
from drillgym.diagnosis.other_reading import other_reading
from drillgym.diagnosis.reselection import KeptCandidate

TERMS = {t.label: t for t in _voltage_terms()}


def _kept(terms, widths, fitted, names, tmp_path):
    cand = Candidate(
        "motor_voltage",
        terms,
        {lb: TERMS[lb].code if lb in TERMS else "min(max(u, -U0), U0)" for lb in terms},
        dict.fromkeys(terms, 0.0),
        0.97,
        1000,
        name="candidate_motor_voltage",
        widths=widths,
    )
    write_effect_file(cand, tmp_path / "cand.py", cand.name)
    through = {p.name: 0.0 for p in MotorVoltageTerms.parameters} | fitted
    return KeptCandidate(cand.effect_file, {}, (), MotorVoltageTerms, through, names, cand)


def test_an_offset_is_read_again_as_a_dead_zone_of_its_size_and_its_file_written_in_its_place(tmp_path):
    kept = _kept(
        {"u³": 0.005, "1": -0.17},
        {},
        {"mv_u3": 3e-4, "mv_offset": -0.398},
        {"mv_u3": "candidate_motor_voltage_c1", "mv_offset": "candidate_motor_voltage_c2"},
        tmp_path,
    )
    other = other_reading(kept)
    assert list(other.candidate.terms) == ["u³", "sat(u, 0.17)"] and other.candidate.terms["sat(u, 0.17)"] == -1.0
    v = other.kept.through_values
    assert v["mv_u3"] == 3e-4 and v["mv_sat"] == -1.0 and v["mv_w"] == pytest.approx(0.17) and v["mv_offset"] == 0.0
    assert "mv_offset" in other.kept.held_terms and "mv_sat" not in other.kept.held_terms
    assert other.kept.file_names == {
        "mv_u3": "candidate_motor_voltage_c1",
        "mv_sat": "candidate_motor_voltage_c2",
        "mv_w": "candidate_motor_voltage_w2",
    }
    written = other.write()
    assert written.spec == kept.spec  # the same file and effect, now the dead zone
    effect = get_effect(written.spec)
    args = {"u": 0.1, "candidate_motor_voltage_c1": 0.0, "candidate_motor_voltage_c2": -1.0}
    assert effect.voltage(**args, candidate_motor_voltage_w2=0.3) == pytest.approx(0.0)  # inside the zone: nothing
    assert effect.voltage(**{**args, "u": 2.0}, candidate_motor_voltage_w2=0.3) == pytest.approx(1.7)


def test_a_dead_zone_is_read_again_as_an_offset_and_a_candidate_with_neither_has_no_other_reading(tmp_path):
    kept = _kept(
        {"sat(u, 0.3)": -1.0},
        {"sat(u, 0.3)": 0.3},
        {"mv_sat": -0.95, "mv_w": 0.32},
        {"mv_sat": "candidate_motor_voltage_c1", "mv_w": "candidate_motor_voltage_w1"},
        tmp_path,
    )
    other = other_reading(kept)
    assert other.candidate.terms == {"1": -0.3} and not other.candidate.widths
    assert other.kept.through_values["mv_offset"] == pytest.approx(-0.3) and other.kept.through_values["mv_sat"] == 0
    assert set(other.kept.held_terms) >= {"mv_sat", "mv_w"}
    plain = _kept({"u³": 0.005}, {}, {"mv_u3": 3e-4}, {"mv_u3": "candidate_motor_voltage_c1"}, tmp_path)
    assert other_reading(plain) is None


def test_the_other_reading_can_start_the_terms_both_share_at_zero_its_own_term_as_before(tmp_path):
    kept = _kept(
        {"u|u|": 0.067, "sign(u)": -0.28},
        {},
        {"mv_uabs": 0.067, "mv_sign": -0.28},
        {"mv_uabs": "candidate_motor_voltage_c1", "mv_sign": "candidate_motor_voltage_c2"},
        tmp_path,
    )
    at_fit, at_zero = other_reading(kept), other_reading(kept, shared_at_zero=True)
    assert list(at_zero.candidate.terms) == list(at_fit.candidate.terms) == ["u|u|", "sat(u, 0.28)"]
    assert at_fit.kept.through_values["mv_uabs"] == 0.067 and at_zero.kept.through_values["mv_uabs"] == 0.0
    assert "mv_uabs" not in at_zero.kept.held_terms  # free from zero, not dropped
    for v in (at_fit.kept.through_values, at_zero.kept.through_values):
        assert v["mv_sat"] == -1.0 and v["mv_w"] == pytest.approx(0.28) and v["mv_sign"] == 0.0


def test_an_encoder_reading_is_read_again_as_the_other_encoders_scale_error(tmp_path):
    from drillgym.diagnosis.reading_terms import EncoderTerms
    from drillgym.diagnosis.sensor_reading import reading_candidate

    cand = replace(reading_candidate("lower_encoder"), name="candidate_lower_encoder")
    cand.terms = {"θl": -0.0116, "1": -0.088, "tanh(ωl/w)": 0.0012}
    cand.widths = {"tanh(ωl/w)": 0.29}
    write_effect_file(cand, tmp_path / "cand.py", cand.name)
    through = {p.name: p.default for p in EncoderTerms.parameters} | {
        "le_scale": -0.0116,
        "le_offset": -0.088,
        "le_play": 0.0012,
        "le_w": 0.29,
    }
    names = {p: f"candidate_lower_encoder_{s}" for p, s in (("le_scale", "c1"), ("le_offset", "c2"), ("le_play", "c3"))}
    kept = KeptCandidate(cand.effect_file, {}, (), EncoderTerms, through, names | {"le_w": "x_w3"}, cand)
    other = other_reading(kept)
    v = other.kept.through_values
    assert v["me_scale"] == pytest.approx(0.0116 / (1 - 0.0116)) and v["me_offset"] == 0.088
    assert v["me_play"] == -0.0012 and v["me_w"] == 0.29
    assert v["le_scale"] == v["le_offset"] == v["le_play"] == 0.0 and "le_scale" in other.kept.held_terms
    assert other.candidate.group == "motor_encoder" and set(other.kept.file_names) == {
        "me_scale",
        "me_offset",
        "me_play",
        "me_w",
    }
    assert other_reading(kept, shared_at_zero=True) is None  # one other reading only
    written = other.write()
    effect = get_effect(written.spec)
    assert effect.channels == ("theta_u",) and written.spec.endswith(":candidate_motor_encoder")


def test_the_alternative_takes_the_kept_candidates_place_at_its_own_fits_values_and_is_written_with_the_whole_models(
    tmp_path,
):
    from types import SimpleNamespace

    from drillgym.diagnosis.other_reading import alternative, readings_of
    from drillgym.diagnosis.reading_terms import EncoderTerms
    from drillgym.diagnosis.sensor_reading import reading_candidate

    fitted = {p.name: p.guess for p in EncoderTerms.parameters} | {"me_scale": -0.0149, "me_offset": 0.002}
    state = SimpleNamespace(
        composition=SimpleNamespace(named=lambda vec: dict(fitted)), result=SimpleNamespace(vector=0)
    )
    fit = SimpleNamespace(
        through=EncoderTerms,
        state=state,
        variance_cut=0.72,
        with_library=(),
        file_names={"me_scale": "me_scale", "me_offset": "me_offset", "me_play": "me_play", "me_w": "me_w"},
    )
    reading = replace(reading_candidate("motor_encoder"), fit=fit)
    kept = _kept({"1": -0.17}, {}, {"mv_offset": -0.17}, {"mv_offset": "candidate_motor_voltage_c1"}, tmp_path)
    kept = replace(kept, candidate=replace(kept.candidate, alternative=reading))
    alt = alternative(kept)
    assert alt.kept.through is EncoderTerms and alt.kept.spec == kept.spec
    assert alt.kept.through_values["me_scale"] == -0.0149 and "le_scale" in alt.kept.held_terms
    assert alt.kept.file_names["me_scale"] == "candidate_motor_encoder_c1"
    # the offset's dead zone shares no term with it: one start of it, then the alternative (its own other readings
    # are tried by identify where it takes the place)
    assert [(o.candidate.group, o.ranked_second) for o in readings_of(kept)] == [
        ("motor_voltage", False),
        ("motor_encoder", True),
    ]
    written = alt.write({"me_scale": -0.0150, "me_offset": 0.001}, "decided by the whole model")
    assert written.candidate.terms["θu"] == -0.0150 and written.candidate.terms["1"] == 0.001
    text = (tmp_path / "cand.py").read_text()
    assert "decided by the whole model" in text and get_effect(written.spec).channels == ("theta_u",)
    assert alternative(replace(kept, candidate=replace(kept.candidate, alternative=replace(reading, fit=None)))) is None
