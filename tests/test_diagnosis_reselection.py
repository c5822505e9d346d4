"""The diagnosis run again with a kept candidate in the model: which candidate enters, and what is held."""

from types import SimpleNamespace

import pytest

from drillgym import RigParams
from drillgym.diagnosis import DiagnosisOptions
from drillgym.diagnosis.reselection import MIN_CANDIDATE_CUT, kept_candidate, reselection_inputs

CANDIDATE = """
from drillgym.effects import Input, Parameter


class CandidateMotorVoltage(Input):
    name = "candidate_motor_voltage"
    configurations = ("upper", "torsional", "lateral", "coupled")
    parameters = (Parameter("candidate_motor_voltage_c1", "V", -2.0, 2.0, 0.0, 0.1, doc="offset", neutral=0.0),)

    def voltage(u, candidate_motor_voltage_c1):
        return u + candidate_motor_voltage_c1
"""


def _diagnosis(cut: float, effect_file: str | None, with_library=()):
    fit = SimpleNamespace(
        variance_cut=cut,
        values={"c1": 0.12, **({"tau_m": 0.03} if with_library else {})},
        with_library=with_library,
        file_name=lambda k: {"c1": "candidate_motor_voltage_c1"}.get(k, k),
        through=None,
        state=None,
    )
    cand = SimpleNamespace(fit=fit, effect_file=effect_file)
    return SimpleNamespace(candidate=cand, params=RigParams().scaled(km=0.97), selected=[])


@pytest.mark.parametrize(("cut", "enters"), [(MIN_CANDIDATE_CUT - 0.01, False), (MIN_CANDIDATE_CUT, True)])
def test_a_candidate_enters_the_model_only_when_its_fit_removes_enough(cut, enters, tmp_path):
    (tmp_path / "c.py").write_text(CANDIDATE)
    kept = kept_candidate(_diagnosis(cut, f"{tmp_path / 'c.py'}:candidate_motor_voltage"))
    assert (kept is not None) is enters
    if enters:  # its values under the names its file gives them
        assert kept.values == {"candidate_motor_voltage_c1": 0.12} and kept.ahead == ()


def test_a_candidate_without_a_file_does_not_enter():
    assert kept_candidate(_diagnosis(0.9, None)) is None


def test_the_model_run_again_holds_the_start_the_lag_ahead_and_the_candidate_refitted(tmp_path):
    """The start model's effects, the lag the candidate's terms were found through, then the candidate, in that
    signal-path order, with their values; refitted with the base (held or not), no discovery; the base parameters
    start where the first diagnosis left them."""
    (tmp_path / "c.py").write_text(CANDIDATE)
    d = _diagnosis(0.8, f"{tmp_path / 'c.py'}:candidate_motor_voltage", with_library=("motor_lag",))
    kept = kept_candidate(d)
    first = DiagnosisOptions(
        base_effects=["input_delay"], effect_params={"delay": 0.01}, discover=True, fixed_base=True, n_joint=3
    )
    params, again = reselection_inputs(d, kept, first)
    assert params == d.params
    assert [e.name for e in again.base_effects] == ["input_delay", "motor_lag", "candidate_motor_voltage"]
    assert again.effect_params == {"delay": 0.01, "tau_m": 0.03, "candidate_motor_voltage_c1": 0.12}
    assert again.refit_model_effects and not again.discover
    assert again.fixed_base and again.n_joint == 3  # the rest of the first diagnosis' settings


def test_a_candidate_fitted_through_the_compiled_terms_is_held_as_them_and_written_as_its_file(tmp_path):
    """The diagnosis run again holds the compiled terms the candidate's fit ran through (one compiled model for
    every recording), its unused terms held at their values; the values map back to the file's names."""
    from drillgym.diagnosis.motor_terms import MotorVoltageTerms
    from drillgym.effects import compose

    (tmp_path / "c.py").write_text(CANDIDATE)
    comp, values = compose([MotorVoltageTerms], {"mv_offset": 0.12})
    d = _diagnosis(0.8, f"{tmp_path / 'c.py'}:candidate_motor_voltage")
    state = SimpleNamespace(composition=comp, result=SimpleNamespace(vector=comp.vector(None, values)), base_names=())
    d.candidate.fit.through, d.candidate.fit.state = MotorVoltageTerms, state
    d.candidate.fit.file_names = {"mv_offset": "candidate_motor_voltage_c1"}
    kept = kept_candidate(d)
    assert kept.through is MotorVoltageTerms and kept.through_values["mv_offset"] == pytest.approx(0.12)
    _, again = reselection_inputs(d, kept, DiagnosisOptions(discover=True))
    assert [e.name for e in again.base_effects] == ["motor_voltage_terms"]
    assert again.effect_params["mv_offset"] == pytest.approx(0.12) and again.effect_params["mv_sat"] == 0.0
    assert set(again.held_effect_params) == {p.name for p in MotorVoltageTerms.parameters} - {"mv_offset"}
    assert kept.in_file({"mv_offset": 0.2, "mv_sat": 0.0, "km": 1.0}) == {"candidate_motor_voltage_c1": 0.2, "km": 1.0}
    # a file whose terms do not map one to one onto the compiled ones is held itself
    d.candidate.fit.file_names = {}
    assert kept_candidate(d).through is None


def test_a_library_effect_named_by_discovery_is_held_and_the_library_selected_again(tmp_path, monkeypatch):
    """Where discovery answers with a library effect (:mod:`drillgym.diagnosis.library_columns`), the candidate's
    file is removed, the answer said in a warning, and the diagnosis runs again with that effect held in the
    model (its values fitted there), as it does with a kept candidate."""
    from drillgym.diagnosis import diagnose, discovery, pipeline
    from drillgym.diagnosis.candidate import Candidate
    from drillgym.identification.synthetic import synthetic_measurement

    rec = synthetic_measurement(
        "torsional", None, duration=20.0, rate_hz=250.0, offset=1.0, seed=5,
        effects=["position_friction"], effect_params={"pf_c1": 0.1, "pf_s1": -0.06},
    )  # fmt: skip
    out = tmp_path / "cand.py"
    real = discovery.discover

    def answered(ex, diagnosis, candidate_out=None, name=None):  # as if the selection had missed it
        if "position_friction" not in diagnosis.selected or "friction_drift" in diagnosis.model:
            return real(ex, diagnosis, candidate_out, name)
        out.write_text("# a candidate's file\n")
        cand = Candidate("lower_friction", {"sign(ωl) cos θl": 0.01}, {}, {}, 0.6, 100, effect_file=f"{out}:c")
        cand.rest = {"library:friction_drift": 0.55}
        return cand, []

    monkeypatch.setattr(pipeline, "discover", answered)
    d = diagnose(rec, discover=True, candidate_out=out)
    assert d.candidate is None and not out.exists(), (d.selected, d.warnings)
    assert any("friction_drift's" in w and "held in the model" in w for w in d.warnings), d.warnings
    again = d.reselection
    assert again is not None and "friction_drift" in again.composition.names
    assert "drift" in again.composition.param_names and again.selected == ["position_friction"], again.text()
