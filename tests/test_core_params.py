"""Parameter set: defaults from docs/model.md, validation naming the parameter, file round trips."""

import json
import math

import pytest

from drillgym.params import BASE_PARAMETERS, N_PARAMS, ParameterError, RigParams


def test_defaults_are_model_md_values():
    p = RigParams()
    assert (p.Ju, p.km, p.Jl, p.ktheta, p.Ts, p.Tc, p.ws, p.delta) == (
        0.4765,
        4.3228,
        0.0414,
        0.0775,
        0.2781,
        0.0473,
        1.4302,
        2.0575,
    )
    assert p.m == pytest.approx(9.9137 + 3.2302)


def test_r4_stick_voltage_and_r6_lateral_eigenfrequency():
    p = RigParams()
    assert p.stick_voltage == pytest.approx(0.1509, abs=5e-5)  # R4
    assert p.lateral_eigenfrequency == pytest.approx(15.04, abs=0.005)  # R6
    assert p.e * p.mr / p.m * 1e3 == pytest.approx(3.69, abs=0.005)  # R6 limit radius


@pytest.mark.parametrize(
    "name,value,fragment",
    [
        ("Ju", -0.1, "'Ju'"),
        ("Jl", float("nan"), "'Jl'"),
        ("ktheta", float("inf"), "'ktheta'"),
        ("e", 0.5, "'e'"),
    ],
)
def test_bad_values_name_the_parameter(name, value, fragment):
    with pytest.raises(ParameterError, match=fragment):
        RigParams().replace(**{name: value})


def test_static_below_slip_friction_is_refused():
    with pytest.raises(ParameterError, match="'Ts'"):
        RigParams().replace(Ts=0.01)


def test_unknown_parameter_is_refused():
    with pytest.raises(ParameterError, match="unknown parameter"):
        RigParams().replace(Jx=1.0)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_file_round_trip_is_exact(tmp_path, suffix):
    p = RigParams().replace(Ts=0.3012345678901234, b=31.25)
    path = p.to_file(tmp_path / f"p{suffix}")
    assert RigParams.from_file(path) == p


def test_missing_field_in_file_names_it(tmp_path):
    d = RigParams().to_dict()
    del d["kθ" if "kθ" in d else "ktheta"]
    path = tmp_path / "p.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ParameterError, match="missing parameter.*ktheta"):
        RigParams.from_file(path, partial=False)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_partial_file_overrides_the_defaults(tmp_path, suffix):
    path = tmp_path / f"p{suffix}"
    path.write_text('{"Ts": 0.3, "b": 31.0}' if suffix == ".json" else "Ts: 0.3\nb: 31.0\n")
    assert RigParams.from_file(path) == RigParams().replace(Ts=0.3, b=31.0)
    path.write_text('{"Ts": 0.3, "Tss": 1}' if suffix == ".json" else "Ts: 0.3\nTss: 1\n")
    with pytest.raises(ParameterError, match="unknown parameter.*Tss"):
        RigParams.from_file(path)


def test_non_number_and_corrupt_file(tmp_path):
    d = RigParams().to_dict()
    d["Ju"] = "heavy"
    (tmp_path / "a.json").write_text(json.dumps(d))
    with pytest.raises(ParameterError, match="'Ju' must be a number"):
        RigParams.from_file(tmp_path / "a.json")
    (tmp_path / "b.json").write_text("{not json")
    with pytest.raises(ParameterError, match="b.json: not valid"):
        RigParams.from_file(tmp_path / "b.json")
    (tmp_path / "c.json").write_bytes(bytes(range(128, 256)))
    with pytest.raises(ParameterError, match=r"c.json: not a parameter file \(not UTF-8 text\)"):
        RigParams.from_file(tmp_path / "c.json")


def test_vector_layout_round_trip():
    p = RigParams().replace(k=3100.0)
    v = p.to_vector()
    assert v.shape == (N_PARAMS,)
    assert RigParams.from_vector(v) == p
    assert set(BASE_PARAMETERS) >= {"Ju", "km", "Ts", "e"}
    assert all(math.isfinite(x) for x in v)


def test_effect_parameters_are_not_rig_parameters():
    """Effects own their parameters (drillgym.effects): RigParams holds the base model only."""
    with pytest.raises(ParameterError, match="unknown parameter"):
        RigParams().replace(tau_m=0.1)


@pytest.mark.parametrize(
    "name, text",
    [
        ("p.json", '{"Jl": 0.04, "Ts": 0.3, "Jl": 0.05}'),
        ("p.yaml", "Jl: 0.04\nTs: 0.3\nJl: 0.05\n"),
        ("m.json", '{"params": {"Jl": 0.04}, "params": {"Ts": 0.3}}'),
    ],
)
def test_a_parameter_file_giving_a_name_twice_is_refused(tmp_path, name, text):
    """A name given twice is ambiguous (the parsers would keep the last one without a word): refused, naming it."""
    (tmp_path / name).write_text(text)
    with pytest.raises(ParameterError, match="given twice") as err:
        RigParams.from_file(tmp_path / name)
    key = "params" if name.startswith("m") else "Jl"
    assert f"'{key}'" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("text", ["Jl: 4.5e-2\n", "Jl: 45e-3\n", "Jl: 4.5E-2\n"])
def test_a_yaml_number_in_exponent_form_is_a_number(tmp_path, text):
    """``45e-3`` is a number in JSON and YAML 1.2; PyYAML's YAML 1.1 reads it as text."""
    (tmp_path / "p.yaml").write_text(text)
    assert RigParams.from_file(tmp_path / "p.yaml").Jl == pytest.approx(0.045)


def test_a_parameter_file_that_is_a_model_with_effects_only_is_refused(tmp_path):
    (tmp_path / "m.json").write_text('{"effects": [{"spec": "motor_lag"}]}')
    with pytest.raises(ParameterError, match=r"model file with effects \(motor_lag\)"):
        RigParams.from_file(tmp_path / "m.json")
