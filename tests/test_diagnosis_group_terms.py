"""Every group's candidate is fitted through its whole group's terms, compiled once for every recording."""

import inspect
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from drillgym.diagnosis.candidate import Candidate
from drillgym.diagnosis.discovery_terms import _groups
from drillgym.diagnosis.effect_file import write_effect_file
from drillgym.diagnosis.group_terms import terms_effect, terms_name, terms_parameter
from drillgym.diagnosis.lateral_terms import outside_terms
from drillgym.effects.file_signature import code_signature

WRITTEN = ("lower_friction", "upper_friction", "string", "lower_force", "lateral_force")
FUNCTION = {"lower_friction": "slip", "upper_friction": "slip", "lateral_force": "force"}


def _terms(group):
    if group == "lateral_force":
        return [(t.label, t.code, 0.0) for t in outside_terms()]
    return [(t.label, t.code, t.at_rest) for t in _groups(False)[group]]


def _candidate(group, picks, rng):
    terms = _terms(group)
    chosen = [terms[i] for i in picks]
    coef = {label: float(rng.normal(0.0, 0.05)) for label, _, _ in chosen}
    return Candidate(
        group,
        coef,
        {label: code for label, code, _ in chosen},
        {label: rest for label, _, rest in chosen},
        0.7,
        500,
        reach={label: 0.3 for label, _, _ in chosen},
    )


def _call(effect, values, args):
    fn = getattr(effect, FUNCTION.get(effect_group(effect), "torque"))
    names = inspect.signature(fn).parameters
    return fn(**{n: values.get(n, args.get(n, 0.0)) for n in names})


def effect_group(effect):
    return effect.name[: -len("_terms")] if effect.name.endswith("_terms") else effect.name[len("candidate_") :]


@pytest.mark.parametrize("group", WRITTEN)
def test_two_recordings_candidates_share_one_compiled_terms_effect_that_acts_as_their_files(group, tmp_path):
    """Two candidates of a group with different terms and coefficients are fitted through effects with the same
    compiled code (the kernel key, :func:`code_signature`), and with the candidate's coefficients (the other terms
    at 0) that effect gives what the candidate's own file gives."""
    rng = np.random.default_rng(3)
    n = len(_terms(group))
    first = _candidate(group, [0, n - 1], rng)
    if group == "lateral_force":  # the brake pad's terms too
        first = _candidate(group, [0, *(i for i, t in enumerate(_terms(group)) if t[0].startswith("T_fl"))], rng)
    second = _candidate(group, sorted(rng.choice(n, size=min(3, n), replace=False)), rng)
    (e1, start1), (e2, start2) = terms_effect(first), terms_effect(second)
    assert e1.name == e2.name == terms_name(group)
    sig = [code_signature(Path(e.__drillgym_file__).read_text(encoding="utf-8")) for e in (e1, e2)]
    assert sig[0] == sig[1]
    assert set(start1) == {terms_parameter(group, label) for label in first.terms}
    for cand, effect, start in ((first, e1, start1), (second, e2, start2)):
        write_effect_file(cand, tmp_path / f"{group}.py")
        from drillgym.diagnosis.effects import get_effect

        own = get_effect(cand.effect_file)
        own_values = {f"{cand.name}_c{i}": c for i, c in enumerate(cand.terms.values(), 1)}
        through_values = {p.name: start.get(p.name, 0.0) for p in effect.parameters}
        for _ in range(5):
            args = {
                "T": 0.3, "direction": 1.0, "omega": 2.0, "speed": 2.0, "theta_l": rng.uniform(-3, 3),
                "theta_u": rng.uniform(-3, 3), "alpha": rng.uniform(-0.3, 0.3), "alpha_dot": rng.uniform(-1, 1),
                "t": rng.uniform(0, 10), "X": rng.normal(0, 1e-3), "Y": rng.normal(0, 1e-3),
                "VX": rng.normal(0, 1e-2), "VY": rng.normal(0, 1e-2), "ws": 1.3, "delta": 1.9,
                "omega_l": rng.uniform(-3, 3), "brake": 1.0, "Ts": 1.0, "Tc": 0.6, "bb": 0.02,
            }  # fmt: skip
            assert np.allclose(_call(own, own_values, args), _call(effect, through_values, args), rtol=1e-12)
        (tmp_path / f"{group}.py").unlink()


def test_a_term_outside_its_group_has_no_parameter():
    """A candidate whose label its group's list does not hold is fitted through its own file."""
    cand = Candidate("string", {"α|α|": 0.1, "not a term": 0.2}, {}, {}, 0.5, 10)
    assert terms_parameter("string", "α|α|") == "string_terms_c1"
    assert terms_effect(cand) is None


def test_a_fitted_value_beyond_the_regressed_bounds_is_written_into_the_candidates_file(tmp_path):
    """The joint fit runs through the group's terms, whose bounds are the group's: a coefficient it takes beyond
    the bounds the candidate's file was written with is written into the file (its guess, bounds around it), so the
    model file holding it reads back; values within them leave the file as it is."""
    from drillgym.diagnosis.discovery_terms import _voltage_terms
    from drillgym.diagnosis.effect_file import covering_file
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.reselection import KeptCandidate, kept_candidate

    terms = {t.label: t for t in _voltage_terms()}
    chosen = ("1", "sat(u, 0.4)")
    cand = Candidate(
        "motor_voltage",
        {"1": 0.05, "sat(u, 0.4)": -0.9},
        {lb: terms[lb].code for lb in chosen},
        dict.fromkeys(chosen, 0.0),
        0.9,
        100,
        reach={"1": 0.05, "sat(u, 0.4)": 0.2},
        widths={"sat(u, 0.4)": 0.4},
    )
    write_effect_file(cand, tmp_path / "c.py")
    effect = get_effect(cand.effect_file)
    inside = {"candidate_motor_voltage_c1": 0.1, "candidate_motor_voltage_c2": -1.0, "candidate_motor_voltage_w2": 0.5}
    written = (tmp_path / "c.py").read_text()
    assert covering_file(cand, inside) == cand.effect_file and (tmp_path / "c.py").read_text() == written
    beyond = {**inside, "candidate_motor_voltage_c1": 0.6}
    bounds = {p.name: (p.lo, p.hi) for p in effect.parameters}
    assert not bounds["candidate_motor_voltage_c1"][0] <= 0.6 <= bounds["candidate_motor_voltage_c1"][1]
    again = get_effect(covering_file(cand, beyond))
    assert again.__drillgym_file__ == effect.__drillgym_file__
    for p in again.parameters:
        assert p.lo <= beyond[p.name] <= p.hi and p.guess == pytest.approx(beyond[p.name])
    u = 1.3
    args = {**beyond, "u": u}
    expected = u + 0.6 - 1.0 * min(max(u, -0.5), 0.5)
    fn = again.voltage
    assert fn(**{n: args[n] for n in inspect.signature(fn).parameters}) == pytest.approx(expected)

    # the diagnosis run again holds the file at the fitted values: a width fitted beyond the file's range (2.6 V
    # where it was written up to 2 V) once stopped it with a ParameterError
    from types import SimpleNamespace

    from drillgym.effects import compose

    wide = {**inside, "candidate_motor_voltage_w2": 2.6}
    fit = SimpleNamespace(
        variance_cut=0.9, values=wide, file_name=lambda k: k, with_library=(), through=None, state=None
    )
    kept = kept_candidate(SimpleNamespace(candidate=replace(cand, fit=fit), selected=[]))
    assert isinstance(kept, KeptCandidate)
    _, values = compose([kept.spec], kept.values)
    assert values["candidate_motor_voltage_w2"] == 2.6


def test_no_fit_makes_the_voltage_at_the_motor_fall_as_the_command_rises(tmp_path):
    """A dead zone is sat(u, w) with coefficient -1 (the motor sees nothing inside the width); below -1 the voltage
    would fall as the command rises, which no drive does.  Let go there, the fit of a dead zone read for a -0.3 V
    offset slid to -3 sat(u, 0.096) and the observer built on it held nothing below 4 rad/s.  The group's terms and
    a candidate's file both stop at -1; the other terms keep their symmetric bounds."""
    from drillgym.diagnosis.discovery_terms import _voltage_terms
    from drillgym.diagnosis.effects import get_effect
    from drillgym.diagnosis.motor_terms import MotorVoltageTerms

    assert {p.name: p.lo for p in MotorVoltageTerms.parameters}["mv_sat"] == -1.0
    terms = {t.label: t for t in _voltage_terms()}
    chosen = ("u|u|", "sat(u, 0.2)")
    for c in (-1.0, -1.4):  # a regressed coefficient below -1 starts at -1
        cand = Candidate(
            "motor_voltage",
            {"u|u|": 0.02, "sat(u, 0.2)": c},
            {lb: terms[lb].code for lb in chosen},
            dict.fromkeys(chosen, 0.0),
            0.9,
            100,
            widths={"sat(u, 0.2)": 0.2},
        )
        write_effect_file(cand, tmp_path / f"c{abs(c)}.py")
        params = {p.name: p for p in get_effect(cand.effect_file).parameters}
        sat = params["candidate_motor_voltage_c2"]
        assert sat.lo == -1.0 and sat.hi == pytest.approx(4 * abs(c)) and sat.guess == -1.0
        assert params["candidate_motor_voltage_c1"].lo == pytest.approx(-0.08)


@pytest.mark.parametrize("group", WRITTEN)
def test_every_groups_terms_effect_takes_no_more_arguments_than_the_kernels_pass(group):
    from drillgym.effects.compile_check import MAX_ARGUMENTS

    rng = np.random.default_rng(1)
    effect, _ = terms_effect(_candidate(group, [0], rng))
    for fn in effect.defined_functions():
        assert len(effect.argument_names(fn)) <= MAX_ARGUMENTS, (group, fn)


def test_a_harmonic_enters_with_its_quadrature():
    """A residual torque a cos 6θu + b sin 6θu with b small, and noise: the greedy regression enters cos 6θu alone
    (b's share is below its gain); the candidate gets sin 6θu beside it, so its own fit can set the phase.  Terms
    that are not harmonics bring nothing."""
    from drillgym.diagnosis.greedy import greedy_terms, with_quadratures

    terms = _groups(False)["upper_force"]
    labels = [t.label for t in terms]
    theta = np.linspace(0.0, 40.0, 4000)
    d = {"t": theta, "thu": theta, "wu": np.full_like(theta, 2.0), "thl": theta, "wl": np.full_like(theta, 2.0)}
    noise = np.random.default_rng(2).normal(0.0, 0.02, theta.size)  # a tenth of the variance, as after smoothing
    y = 0.08 * np.cos(6 * theta) - 0.006 * np.sin(6 * theta) + noise
    cols = [np.asarray(t.values(d), dtype=float) for t in terms]
    chosen, _ = greedy_terms(cols, y, float(y @ y))
    assert [labels[j] for j in chosen] == ["cos 6θu"]
    both = with_quadratures(chosen, labels)
    assert [labels[j] for j in both] == ["cos 6θu", "sin 6θu"]
    c, *_ = np.linalg.lstsq(np.column_stack([cols[j] for j in both]), y, rcond=None)
    np.testing.assert_allclose(c, [0.08, -0.006], atol=2e-3)
    assert with_quadratures([labels.index("sin 6θu")], labels) == [labels.index("sin 6θu"), labels.index("cos 6θu")]
    plain = [i for i, label in enumerate(labels) if "cos" not in label and "sin" not in label][:1]
    assert with_quadratures(plain, labels) == plain
