"""Discovery on the lateral side: the residual lateral force regressed on forces shaped by physics, written as a
lateral Force effect file, on recordings of the independent rig (benchmarks/bench_diagnosis_rig.py)."""

from pathlib import Path

import numpy as np
import pytest
from test_diagnosis_selection import independent_rig

from drillgym import RigParams
from drillgym.diagnosis.discovery import MIN_EXPLAINED_SHARE, Candidate, find_candidate, write_effect_file
from drillgym.diagnosis.lateral_discovery import LATERAL_GROUP, lateral_candidate
from drillgym.diagnosis.lateral_terms import lateral_terms
from drillgym.diagnosis.sparse import residual_torques
from drillgym.effects import compose
from drillgym.identification.experiment import prepare_experiment

ROOT = Path(__file__).resolve().parents[1]


def _coupled(effects: dict, seed: int = 5):
    """12 s of ramps at 200 Hz about 2.6 V on the independent rig, coupled (whirl through the resonance)."""
    return independent_rig()("coupled", "ramps", 12.0, 200.0, seed, effects, {}, 2.6, 1.5)


def _residual(effects: dict, seed: int = 5):
    """The residual torques and lateral forces of the nominal model on the rig's recording."""
    ex = prepare_experiment(_coupled(effects, seed), "coupled", compare_rate_hz=200.0)
    return residual_torques(ex, RigParams())


def _best(effects: dict, seed: int = 5) -> Candidate | None:
    """discovery's best group on the residual of the nominal model."""
    p, rt = RigParams(), _residual(effects, seed)
    return find_candidate(rt, rt.u_motor, p.Ju, p.Jl, True, p.ws, p.delta, p.km)


@pytest.mark.parametrize(
    ("effect", "values", "term", "size"),
    [
        ("lateral_cubic", {"k3": 6e7}, "r²·(X, Y)", -6e7),
        ("lateral_quadratic_damping", {"c2": 300.0}, "|V|·(VX, VY)", -300.0),
    ],
)
def test_a_lateral_force_outside_the_library_is_the_lateral_group(effect, values, term, size):
    """A stiffening spring −k3 r² (X, Y) or a quadratic drag −c2 |V| V: the lateral group wins over every torque
    group, its first term has the force's shape and (alone) its size."""
    cand = _best({effect: values})
    assert cand is not None and cand.group == LATERAL_GROUP, cand
    assert next(iter(cand.terms)) == term, cand.expression()
    assert cand.terms[term] == pytest.approx(size, rel=0.15), cand.expression()
    assert cand.explained > MIN_EXPLAINED_SHARE and cand.explained > 2 * max(
        v for g, v in cand.rest.items() if g != LATERAL_GROUP
    ), cand.rest


def test_a_library_anisotropy_is_not_proposed_as_a_force_outside_the_library():
    """kx ≠ ky and bx ≠ by (the library's lateral_anisotropy, dk = 250 N/m, db = 3 N s/m) left out of the model:
    regressed jointly with the library's shapes, no term outside the library explains the residual; regressed on
    every shape alone, it is (X, −Y) and (VX, −VY) with the effect's own values (its force is
    (−dk X − db VX, dk Y + db VY))."""
    rt = _residual({"lateral_anisotropy": {"dk": 250.0, "db": 3.0}})
    outside = lateral_candidate(rt)
    assert outside is None or outside.explained < MIN_EXPLAINED_SHARE, outside.expression()
    every = lateral_candidate(rt, terms=lateral_terms(), library=False)
    assert set(every.terms) == {"(X, −Y)", "(VX, −VY)"}, every.expression()
    assert every.terms["(X, −Y)"] == pytest.approx(-250.0, rel=0.1)
    assert every.terms["(VX, −VY)"] == pytest.approx(-3.0, rel=0.3)


def test_a_string_effect_is_not_taken_for_a_lateral_force():
    """A cubic string on the coupled rig: the string group, the lateral group's share below the bar."""
    cand = _best({"string_cubic": {"c3": 0.015}})
    assert cand.group == "string", cand.expression()
    assert cand.rest.get(LATERAL_GROUP, 0.0) < MIN_EXPLAINED_SHARE, cand.rest


def test_no_lateral_candidate_on_the_torsional_configuration():
    ts = independent_rig()("torsional", "ramps", 6.0, 200.0, 5, {}, {}, 2.6, 1.5)
    rt = residual_torques(prepare_experiment(ts, "torsional", compare_rate_hz=200.0), RigParams())
    assert rt.force_X is None and lateral_candidate(rt) is None


def test_lateral_candidate_file_is_a_lateral_force(tmp_path):
    """The file is a lateral Force whose force(X, Y, VX, VY) is the terms' sum, fixed frame."""
    terms = {t.label: t for t in lateral_terms()}
    chosen = {"r²·(X, Y)": -5e7, "|V|·(VX, VY)": -200.0, "(cos θl, sin θl)": 0.3}
    cand = Candidate(
        LATERAL_GROUP,
        chosen,
        {k: terms[k].code for k in chosen},
        dict.fromkeys(chosen, 0.0),
        0.9,
        1000,
    )
    text = write_effect_file(cand, tmp_path / "lat.py").read_text()
    assert 'acts_on = "lateral"' in text and "def force(" in text
    comp, values = compose([cand.effect_file])
    eff = comp.effects[0]
    X, Y, VX, VY, th = 2e-3, -1e-3, 0.01, 0.02, 0.7
    fx, fy = eff.force(X, Y, VX, VY, th, *values.values())
    r2, v = X * X + Y * Y, np.hypot(VX, VY)
    assert fx == pytest.approx(-5e7 * r2 * X - 200.0 * v * VX + 0.3 * np.cos(th))
    assert fy == pytest.approx(-5e7 * r2 * Y - 200.0 * v * VY + 0.3 * np.sin(th))


@pytest.mark.parametrize(("truth", "verdict"), [("lateral_cubic", True), ("lateral_coulomb", False)])
def test_a_library_coulomb_standing_in_for_a_stiffening_spring_is_named(truth, verdict):
    """The selection took lateral_coulomb (at the size a fit gives it on a stiffening spring): with a stiffening
    spring in the recording the residual without it is r², not Coulomb, and the diagnosis says so; with Coulomb
    friction in the recording it says nothing."""
    from types import SimpleNamespace

    from drillgym.diagnosis.lateral_library import library_versus_outside

    values = {"lateral_cubic": {"k3": 6e7}, "lateral_coulomb": {"Fc_lat": 1.5}}[truth]
    ex = prepare_experiment(_coupled({truth: values}), "coupled", compare_rate_hz=200.0)
    comp, _ = compose(["lateral_coulomb"])
    vec = comp.vector(RigParams(), {"Fc_lat": 1.5})
    rt = residual_torques(ex, vec, effects=comp)
    outside = [t for t in lateral_terms() if t.label == "r²·(X, Y)"]
    cand = lateral_candidate(rt, terms=outside, library=False) or Candidate(
        LATERAL_GROUP, {"r²·(X, Y)": -1e7}, {}, {}, 0.5, 1
    )
    diagnosis = SimpleNamespace(composition=comp, vector=vec, selected=["lateral_coulomb"])
    found = library_versus_outside(ex, diagnosis, cand)
    assert (found is not None) == verdict, found
    if verdict:
        assert found.library == "lateral_coulomb" and next(iter(found.outside.terms)) == "r²·(X, Y)"
        assert "r²" in found.line() and "not Coulomb friction" in found.line(), found.line()


def test_a_library_effect_named_as_another_force_is_left_out_of_the_model_beside_the_candidate():
    """The selection again beside a kept candidate neither holds nor screens the library effect the residual said
    is another force; the verdict says which way it went."""
    from types import SimpleNamespace

    from drillgym.configurations import Configuration
    from drillgym.diagnosis import DiagnosisOptions
    from drillgym.diagnosis.lateral_library import LateralVerdict
    from drillgym.diagnosis.reselection import KeptCandidate, reselection_inputs

    cand = Candidate(LATERAL_GROUP, {"r²·(X, Y)": -6e7}, {}, {}, 0.9, 1)
    spec = f"{ROOT}/examples/effects/string_cubic.py:string_cubic"  # the kept candidate's file (any effect file)
    kept = KeptCandidate(spec, {}, ("lateral_coulomb",))
    first = SimpleNamespace(params=RigParams(), config=Configuration.COUPLED)
    for options in (DiagnosisOptions(), DiagnosisOptions(effects=["lateral_coulomb", "lateral_anisotropy"])):
        _, again = reselection_inputs(first, kept, options, left_out=("lateral_coulomb",))
        held = [getattr(e, "name", e) for e in again.base_effects]
        assert "lateral_coulomb" not in held and held[-1] == "string_cubic", held
        names = [getattr(e, "name", e) for e in again.effects]
        assert "lateral_coulomb" not in names and "lateral_anisotropy" in names, names
    _, same = reselection_inputs(first, kept, DiagnosisOptions())
    assert "lateral_coulomb" in [getattr(e, "name", e) for e in same.base_effects] and same.effects is None
    verdict = LateralVerdict("lateral_coulomb", cand, 0.9, 0.2, {"Fc_lat": 7.5})
    assert verdict.line(left_out=True).endswith("lateral_coulomb is left out of the model the candidate enters")
    assert "stays in the model" in verdict.line(left_out=False)


@pytest.mark.slow
def test_diagnosis_proposes_a_stiffening_spring_that_halves_the_lvdt_misfit(tmp_path):
    """The whole diagnosis (selection, discovery, the candidate's own fit, the selection again) on a stiffening
    spring: the candidate is the lateral force r²·(X, Y), its fit at least halves both LVDTs' misfit, and no
    library lateral effect is named in its place."""
    from drillgym.diagnosis import diagnose

    d = diagnose(_coupled({"lateral_cubic": {"k3": 6e7}}), discover=True, candidate_out=tmp_path / "cand.py")
    c = d.candidate
    assert c is not None and c.group == LATERAL_GROUP and next(iter(c.terms)) == "r²·(X, Y)", d.text()
    assert c.terms["r²·(X, Y)"] < 0 and c.fit is not None
    for ch in ("x", "y"):
        assert c.fit.after.channels[ch] <= 0.5 * c.fit.before.channels[ch], c.fit.line()
    named = set(d.selected) | set(d.reselection.selected if d.reselection is not None else ())
    assert not named & {"lateral_coulomb", "lateral_anisotropy"}, d.text()


def test_a_brake_pad_at_a_fixed_point_is_a_force_that_follows_the_brakes_torque():
    """A pad on the rim at φ pushes the centre with its friction T_fl / R_pad along the tangent there: with the
    model's LVDT offset holding the constant part (its normal force reads as one), the residual lateral force
    regressed on the terms gives back T_fl (sin φ, −cos φ) / R_pad."""
    from dataclasses import replace

    phi, radius = 0.64, 0.076
    rt = _residual({"brake_contact": {"N": 1.25, "phi": phi, "R_pad": radius}}, seed=43)
    cand = lateral_candidate(replace(rt, effects=("lvdt_offset",)))
    assert cand is not None and set(cand.terms) == {"T_fl·(1, 0)", "T_fl·(0, 1)"}, cand.expression()
    assert cand.terms["T_fl·(1, 0)"] == pytest.approx(np.sin(phi) / radius, rel=0.05)
    assert cand.terms["T_fl·(0, 1)"] == pytest.approx(-np.cos(phi) / radius, rel=0.05)
    # the constant force beside the terms (the pad's normal force, 1.25 N, and the friction's mean the terms add),
    # which the model's offset takes when the candidate enters
    fx, fy = cand.constant_force
    assert np.isfinite(fx) and np.isfinite(fy) and 0.3 < np.hypot(fx, fy) < 10.0
    assert lateral_candidate(rt).constant_force is None  # no offset in the model: the constant forces are terms


def test_the_candidates_fit_starts_the_models_offset_where_the_regression_puts_it():
    from types import SimpleNamespace

    from drillgym.diagnosis.candidate_fit import _offset_start

    comp, values = compose(["lvdt_offset"], {"lvdt_x0": 1e-3, "lvdt_y0": -2e-3})
    vec = comp.vector(None, values)
    k = vec[comp.param_index("k")]
    out = _offset_start(SimpleNamespace(constant_force=(3.0, -1.5)), comp, vec)
    assert out[comp.param_index("lvdt_x0")] == pytest.approx(1e-3 + 3.0 / k)
    assert out[comp.param_index("lvdt_y0")] == pytest.approx(-2e-3 - 1.5 / k)
    assert _offset_start(SimpleNamespace(constant_force=None), comp, vec) is vec


def test_the_lateral_group_is_weighed_by_the_lvdts_misfit_against_the_angles():
    from types import SimpleNamespace

    from drillgym.diagnosis.discovery import group_weights

    assert group_weights(SimpleNamespace(channels={"theta_u": 2.0, "theta_l": 1.5, "x": 40.0, "y": 20.0})) == {
        LATERAL_GROUP: 400.0
    }
    assert group_weights(SimpleNamespace(channels={"theta_u": 2.0, "theta_l": 1.5})) == {}
    assert group_weights(None) == {}


#: a reading the selection took a library effect for: the rig's effects, seed, the library effect, the reading's
#: group, term and true value, the words that name the effect, and the rig's library effects beside the reading
READINGS_IN_PLACE = [
    (
        {"lvdt_scale": {"lvdt_kx": 0.0423}, "position_friction": {"pf_c1": -0.095, "pf_s1": -0.071}},
        42,
        "lateral_anisotropy",
        ("lvdt_x", "x", 0.0423),
        "a stiffness that differs in x and y",
        {"position_friction"},
    ),
    (
        {"lower_encoder_offset": {"enc_off_l": 0.03}},
        5,
        "lvdt_skew",
        ("lower_encoder", "1", 0.03),
        "LVDTs whose axes are not square",
        set(),
    ),
]


@pytest.mark.parametrize(("hidden", "seed", "library", "reading", "words", "beside"), READINGS_IN_PLACE)
def test_a_reading_is_found_where_the_selection_took_a_library_effect_for_it(
    tmp_path, hidden, seed, library, reading, words, beside
):
    """A 4 % gain of the x LVDT draws the ellipse a stiffness difference draws (lateral_anisotropy); the lower
    encoder's zero 30 mrad off the motor's turns the angle the unbalance is drawn at, the orbit's phase that
    lvdt_skew draws nearly.  The selection takes the library effect, which leaves the LVDTs near the noise, so no
    reading is screened.  Fitted in its place, the sensor's reading leaves clearly less on the LVDTs: it is the
    candidate (within 15 %), and the library selected again beside it no longer takes the effect: the LVDTs'
    misfit halved, every channel at the noise."""
    from drillgym.diagnosis import diagnose

    group, term, truth = reading
    d = diagnose(_coupled(hidden, seed=seed), discover=True, candidate_out=tmp_path / "cand.py")
    assert library in d.selected, d.text()  # what the selection alone takes
    c = d.candidate
    assert c is not None and c.group == group, d.text()
    assert c.terms[term] == pytest.approx(truth, rel=0.15)
    assert any(f"rather than {words}" in w for w in d.warnings)
    final = d.final()
    assert library not in final.selected and beside <= set(final.selected), final.text()
    assert final.unexplained.explained, final.unexplained.channels
    assert max(final.unexplained.channels[ch] for ch in ("x", "y")) < 0.5 * d.unexplained.channels["x"]


def test_a_library_effect_the_terms_stand_for_is_held_and_the_force_beside_it_found(tmp_path):
    """A cubic lateral spring beside position friction (the friction skipped by the split halves): discovery's best
    terms are the friction's own shape on the lower disc, and a sensor's reading passes its screen; where the terms
    win over the readings, the library effect they stand for is the answer (no outside file for it), and discovery
    run again beside it finds the spring as a lateral force: the final model leaves the LVDTs near the noise."""
    from drillgym.diagnosis import diagnose

    effects = {"lateral_cubic": {"k3": 6.68e7}, "position_friction": {"pf_c1": 0.071, "pf_s1": -0.111}}
    d = diagnose(_coupled(effects, seed=1), discover=True, candidate_out=tmp_path / "candidate.py")
    assert d.candidate is None and d.reselection is not None
    assert "position_friction" in d.reselection.composition.names
    found = d.reselection.candidate
    assert found is not None and found.group == "lateral_force" and next(iter(found.terms)) == "r²·(X, Y)"
    final = d.final().unexplained
    assert max(final.channels["x"], final.channels["y"]) < 6.0, final.channels


def test_a_drags_own_fit_weighs_the_lvdts_by_their_noise_and_halves_their_misfit(tmp_path):
    """A quadratic drag −c2 |V| V (c2 = 865 N s²/m²): the selection weights the sensors by their misfit (the LVDTs
    at 6.6 noise units, the encoders at 2), and the candidate's fit on those weights traded the drag for b at its
    bound (6.65 -> 5.35 noise units on the LVDTs); weighed by the noise, as it is judged, it halves both LVDTs'
    misfit with the drag near its size."""
    from drillgym.diagnosis import diagnose

    d = diagnose(
        _coupled({"lateral_quadratic_damping": {"c2": 865.0}}, seed=0), discover=True, candidate_out=tmp_path / "c.py"
    )
    c = d.candidate
    assert c is not None and c.group == LATERAL_GROUP and next(iter(c.terms)) == "|V|·(VX, VY)", d.text()
    for ch in ("x", "y"):
        assert c.fit.after.channels[ch] <= 0.5 * c.fit.before.channels[ch], c.fit.line()
    (value,) = [v for v in c.fit.values.values()]
    assert value == pytest.approx(-865.0, rel=0.3), c.fit.line()
