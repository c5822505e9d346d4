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
    )
    cand = SimpleNamespace(fit=fit, effect_file=effect_file)
    return SimpleNamespace(candidate=cand, params=RigParams().scaled(km=0.97))


@pytest.mark.parametrize(("cut", "enters"), [(MIN_CANDIDATE_CUT - 0.01, False), (MIN_CANDIDATE_CUT, True)])
def test_a_candidate_enters_the_model_only_when_its_fit_removes_enough(cut, enters):
    kept = kept_candidate(_diagnosis(cut, "c.py:candidate_motor_voltage"))
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
