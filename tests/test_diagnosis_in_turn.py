"""Candidates outside the library found in turn: once one is kept and the library selected again beside it, the
diagnosis looks for the next on that model's residual, up to ``max_candidates``."""

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from drillgym import RigParams
from drillgym.configurations import Configuration
from drillgym.diagnosis import DiagnosisOptions
from drillgym.diagnosis.discovery import Candidate
from drillgym.diagnosis.effect_file import candidate_name
from drillgym.diagnosis.pipeline import _not_held
from drillgym.diagnosis.reselection import KeptCandidate, next_candidate_out, reselection_inputs
from drillgym.diagnosis.results import Diagnosis
from drillgym.errors import InputError, InputTypeError

ROOT = Path(__file__).resolve().parents[1]
CUBIC = f"{ROOT}/examples/effects/string_cubic.py:string_cubic"
BACKLASH = f"{ROOT}/examples/effects/string_backlash.py:string_backlash"


def test_the_next_candidates_file_goes_beside_the_first():
    assert next_candidate_out("run/rec_candidate.py") == Path("run/rec_candidate_2.py")
    assert next_candidate_out(Path("run/rec_candidate_2.py")) == Path("run/rec_candidate_3.py")
    assert next_candidate_out(None) is None


def test_the_selection_again_looks_for_the_next_candidate_while_the_budget_allows(tmp_path):
    first = SimpleNamespace(params=RigParams(), config=Configuration.TORSIONAL)
    kept = KeptCandidate(CUBIC, {}, ())
    out = tmp_path / "rec_candidate.py"
    _, again = reselection_inputs(first, kept, DiagnosisOptions(discover=True, candidate_out=out, max_candidates=2))
    assert again.discover and again.max_candidates == 1 and again.candidate_out == tmp_path / "rec_candidate_2.py"
    _, last = reselection_inputs(first, KeptCandidate(BACKLASH, {}, ()), again)
    assert not last.discover and last.candidate_out is None
    assert [getattr(e, "name", e) for e in last.base_effects] == ["string_cubic", "string_backlash"]
    _, one = reselection_inputs(first, kept, DiagnosisOptions(discover=True))
    assert not one.discover  # one candidate unless asked for more


def test_a_library_effect_named_by_discovery_takes_no_candidates_turn(tmp_path):
    """A library effect discovery named in a candidate's place (held in the model) leaves the search for an effect
    outside the library to the diagnosis run again: a dead zone beside the position friction it named."""
    first = SimpleNamespace(params=RigParams(), config=Configuration.TORSIONAL)
    out = tmp_path / "rec_candidate.py"
    opts = DiagnosisOptions(discover=True, candidate_out=out)
    _, again = reselection_inputs(first, KeptCandidate("position_friction", {}, ()), opts, library=True)
    assert again.discover and again.max_candidates == 1 and again.candidate_out == out
    assert [getattr(e, "name", e) for e in again.base_effects] == ["position_friction"]
    _, kept = reselection_inputs(first, KeptCandidate(CUBIC, {}, ()), opts)
    assert not kept.discover and kept.candidate_out is None


@pytest.mark.parametrize(("value", "error"), [(0, InputError), (1.5, InputTypeError), (True, InputTypeError)])
def test_max_candidates_is_a_count(value, error):
    with pytest.raises(error, match="max_candidates"):
        DiagnosisOptions(max_candidates=value)


def test_a_group_the_model_holds_already_is_not_proposed_again():
    """A second candidate of the group the first was found in is the first's terms again (and its effect would
    have the first's name): it is not proposed; an alternative of that group is dropped from another group's."""
    voltage = Candidate("motor_voltage", {"sat(u, 0.5)": -0.8}, {}, {}, 0.9, 1)
    upper = Candidate("upper_force", {"sin(θu)": 0.1}, {}, {}, 0.8, 1)
    held = {candidate_name("motor_voltage"), "motor_lag"}
    assert _not_held(voltage, held) is None
    upper.alternative = voltage
    kept = _not_held(upper, held)
    assert kept.group == "upper_force" and kept.alternative is None and upper.alternative is voltage
    assert _not_held(None, held) is None


def test_the_chain_of_diagnoses_ends_at_the_model_with_every_candidate():
    base = Diagnosis([], Configuration.TORSIONAL, 1.0, {}, 1.0, None)
    second = replace(base, selected=["string_damping"])
    first_again = replace(base, selected=["motor_lag"], reselection=second)
    d = replace(base, reselection=first_again)
    assert d.in_turn() == [d, first_again, second] and d.final() is second
    assert base.final() is base and base.candidate_lines() == []


def test_the_selection_again_starts_from_the_base_the_candidates_fit_ended_at():
    """A candidate fitted with the base parameters freed holds its values beside them (a brake pad's friction with
    the lateral stiffness 7 % up): the selection again starts there, not at the first diagnosis' base."""
    import numpy as np

    from drillgym.diagnosis.reselection import _fitted_base

    first = SimpleNamespace(params=RigParams(), config=Configuration.TORSIONAL)
    moved = RigParams().scaled(k=1.07, km=0.99)
    start, _ = reselection_inputs(first, KeptCandidate(CUBIC, {}, (), base=moved), DiagnosisOptions())
    assert start == moved
    start, _ = reselection_inputs(first, KeptCandidate(CUBIC, {}, ()), DiagnosisOptions())
    assert start == first.params
    vector = np.concatenate([moved.to_vector(), [0.3]])
    freed = SimpleNamespace(base_names=("k", "km"), result=SimpleNamespace(vector=vector))
    assert _fitted_base(freed) == moved
    assert _fitted_base(SimpleNamespace(base_names=(), result=freed.result)) is None


def test_the_first_selection_is_held_where_the_selection_again_ends_worse_than_the_candidates_fit():
    """The selection run again may lose an effect the candidate's model held (a brake pad beside the anisotropy):
    judged against the candidate's own fit, the model it was fitted in is then held, at the fit's values."""
    from drillgym.diagnosis.reselection import WORSE_BY, worse_than_candidate

    fit = SimpleNamespace(after=SimpleNamespace(ratio_to_noise=2.0))
    first = SimpleNamespace(
        params=RigParams(),
        config=Configuration.TORSIONAL,
        selected=["string_damping", "motor_lag"],
        candidate=SimpleNamespace(fit=fit),
    )
    kept = KeptCandidate(
        CUBIC,
        {},
        (),
        fitted_values={"dtheta": 0.004, "tau_m": 0.03, "unused": 1.0},
        fitted_with=("string_damping", "motor_lag"),
    )
    _, free = reselection_inputs(first, kept, DiagnosisOptions())
    assert [getattr(e, "name", e) for e in free.base_effects] == ["string_cubic"]
    _, held = reselection_inputs(first, kept, DiagnosisOptions(), left_out=("motor_lag",), hold_selected=True)
    assert [getattr(e, "name", e) for e in held.base_effects] == ["string_damping", "motor_lag", "string_cubic"]
    assert held.effect_params["dtheta"] == 0.004 and held.effect_params["tau_m"] == 0.03
    again = SimpleNamespace(unexplained=SimpleNamespace(ratio_to_noise=WORSE_BY * 2.0 + 0.1))
    assert worse_than_candidate(again, first)
    assert not worse_than_candidate(SimpleNamespace(unexplained=SimpleNamespace(ratio_to_noise=2.5)), first)
