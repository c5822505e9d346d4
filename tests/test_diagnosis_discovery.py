"""Discovery beyond the library: candidate effects from the residual torques, written as effect files and
fitted by ``identify --add-effect``."""

import json
from pathlib import Path

import pytest
from test_diagnosis_selection import independent_rig
from test_identification_effects import scipy_cubic_string
from typer.testing import CliRunner

from drillgym import RigParams
from drillgym.cli import app
from drillgym.diagnosis import diagnose
from drillgym.diagnosis.discovery import Candidate, write_effect_file
from drillgym.effects import compose
from drillgym.io import write_timeseries


def test_candidate_file_is_a_valid_effect(tmp_path):
    cand = Candidate(
        "lower_friction",
        {"ωl|ωl|": 0.004, "sign(ωl) exp(−|ωl|/1)": -0.01},
        {"ωl|ωl|": "omega * speed", "sign(ωl) exp(−|ωl|/1)": "direction * math.exp(-speed / 1.0)"},
        {"ωl|ωl|": 0.0, "sign(ωl) exp(−|ωl|/1)": 1.0},
        0.8,
        1000,
    )
    path = write_effect_file(cand, tmp_path / "cand.py")
    comp, values = compose([cand.effect_file])
    assert comp.names == ("candidate_lower_friction",)
    assert values == {"candidate_lower_friction_c1": 0.004, "candidate_lower_friction_c2": -0.01}
    assert "def stick" in path.read_text()
    assert cand.to_json()["dof"] == 2 and "ωl|ωl|" in cand.expression()


def _voltage_candidate():
    return Candidate(
        "motor_voltage",
        {"sat(u, 0.3)": -0.9, "|u|": 0.06},
        {"sat(u, 0.3)": "min(max(u, -U0), U0)", "|u|": "abs(u)"},
        {"sat(u, 0.3)": 0.0, "|u|": 0.0},
        0.9,
        1000,
        widths={"sat(u, 0.3)": 0.3},
    )


@pytest.mark.parametrize("low, high, reverses", [(0.0, 5.0, False), (-5.0, 0.0, False), (-1.0, 5.0, True)])
def test_voltage_candidate_on_a_command_that_never_reverses_is_odd(tmp_path, low, high, reverses):
    """|u| is the command itself (or its opposite) where the command keeps one sign: the file writes it as such, so
    the model's motor reverses with the command; on a command of both signs |u| stays."""
    import numpy as np

    from drillgym.diagnosis.discovery_terms import odd_form
    from drillgym.diagnosis.effects import get_effect

    cand = odd_form(_voltage_candidate(), np.linspace(low, high, 101))
    text = write_effect_file(cand, tmp_path / "cand.py").read_text()
    effect = get_effect(cand.effect_file)
    values = {p.name: p.value for p in effect.parameters}
    v = effect.voltage
    odd = all(abs(v(u, **values) + v(-u, **values)) < 1e-12 for u in (0.1, 0.5, 2.0, 4.0))
    assert odd is not reverses
    assert ("never reversed" in text) is not reverses
    u = 0.5 * (low + high) or 2.0  # on the recording's side, both forms give the same voltage
    assert abs(v(u, **values) - _voltage_candidate_value(u, values)) < 1e-12


def _voltage_candidate_value(u, values):
    c1, c2, w = (values[f"candidate_motor_voltage_{k}"] for k in ("c1", "c2", "w1"))
    return u + c1 * min(max(u, -w), w) + c2 * abs(u)


@pytest.mark.slow
def test_cli_outside_the_library_candidate_file_halves_the_error(tmp_path):
    ts = scipy_cubic_string(0.015, duration=14.0, rate_hz=250.0)
    data = write_timeseries(tmp_path / "rec.csv", ts)
    out = tmp_path / "cand.py"
    r = CliRunner().invoke(app, ["diagnose", str(data), "--json", "--candidate-out", str(out)])
    assert r.exit_code == 0, r.output
    js = json.loads(r.output)
    assert js["selected"] == [], js["ranking"]
    assert {"effect", "score", "significant", "fitted"} <= set(js["ranking"][0])
    assert isinstance(js["base_parameters"], dict)
    cand = js["candidate"]
    assert cand is not None and "α³" in cand["expression"] and cand["dof"] >= 1 and cand["explained"] > 0.5
    assert Path(cand["effect_file"].rsplit(":", 1)[0]) == out and out.exists()
    r2 = CliRunner().invoke(
        app, ["identify", str(data), "--add-effect", cand["effect_file"], "--json", "--out", str(tmp_path / "p.json")]
    )
    assert r2.exit_code == 0, r2.output
    fit = json.loads(r2.output)
    for c in ("theta_l", "alpha"):  # the user watches the error fall: at least halved
        assert 1 - fit["r2_after"][c] <= 0.5 * (1 - fit["r2_before"][c]), fit


def test_candidate_found_on_the_lower_disc_when_the_upper_disc_is_noise():
    """Free play in the string (a torque −kθ sat(α, g)) seen on the lower disc, the upper disc's residual
    torque dominated by derivative noise: the string group is found with the right sign and size."""
    import numpy as np

    from drillgym.configurations import N_STATE
    from drillgym.diagnosis.discovery import find_candidate
    from drillgym.diagnosis.sparse import ResidualTorque

    rng = np.random.default_rng(3)
    p = RigParams()
    t = np.arange(0, 30.0, 1 / 250)
    wu = 2.0 + 1.5 * np.sin(3.0 * t)
    wl = 2.0 + 1.5 * np.sin(3.0 * t - 0.8)
    S = np.zeros((t.size, N_STATE))
    S[:, 0] = np.cumsum(wu) / 250
    S[:, 1] = np.cumsum(wl) / 250
    S[:, 1] -= np.mean(S[:, 1] - S[:, 0])  # the twist α swings about zero (±0.4 rad), through the free play
    S[:, 2], S[:, 3] = wu, wl
    alpha = S[:, 1] - S[:, 0]
    deficit = -p.ktheta * np.clip(alpha, -0.1, 0.1)  # what the string lacks against kθ α
    tau_l = -deficit
    tau_u = deficit + 0.3 * rng.standard_normal(t.size)
    rt = ResidualTorque(t, tau_u, tau_l, S, np.ones(t.size, bool))
    cand = find_candidate(rt, np.zeros(t.size), p.Ju, p.Jl)
    assert cand is not None and cand.group == "string", cand
    assert cand.explained > 0.5, cand.explained
    sats = [(k, v) for k, v in cand.terms.items() if k.startswith("sat")]
    assert len(sats) == 1, cand.terms
    ((label, coef),) = sats
    g = float(label.split(",")[1].strip(" )"))
    assert coef < 0 and abs(coef * min(g, 1.0)) == pytest.approx(p.ktheta * 0.1, rel=0.5), cand.terms


def test_an_upper_disc_friction_is_discovered_while_the_lower_disc_is_stuck():
    """Each disc's torque balance holds while that disc slips, whatever the other one does: on an independent
    rig whose lower disc hardly turns (20 s of ramps about 0.83 V, ±3 V), an upper-disc Stribeck bump outside the
    library (0.15 N m, 0.5 rad/s) was missed, the residual torques having been taken only where the lower
    disc slips; it is found on the upper disc's own rows, with its size and speed."""
    import numpy as np

    from drillgym.diagnosis.discovery import discover
    from drillgym.diagnosis.sparse import residual_torques
    from drillgym.identification.experiment import prepare_experiment

    ts = independent_rig()(
        "torsional", "ramps", 20.0, 500.0, 1979, {"upper_stribeck": {"Tsu": 0.15, "wsu": 0.5}}, {}, 0.83, 3.0
    )
    d = diagnose(ts)
    fine = prepare_experiment(ts, compare_rate_hz=250.0)
    rt = residual_torques(fine, d.vector, effects=d.composition)
    assert np.any(rt.upper_valid & ~rt.lower_valid)  # the upper disc's rows while the lower disc is stuck
    assert np.all(np.isnan(rt.tau_l[~rt.slip])) and np.all(np.isfinite(rt.tau_u[rt.upper_valid]))
    cand, _ = discover(fine, d)
    assert cand is not None and cand.group == "upper_friction", cand
    ((label, coef),) = [(k, v) for k, v in cand.terms.items() if "ωu/0.5" in k]
    assert coef == pytest.approx(0.15, rel=0.25), cand.terms


def _position_friction_residual(rng):
    """A lower disc turning at 2 ± 0.8 rad/s, 0.3 rad behind the upper one, with a position friction
    (pf_c1 = 0.12, pf_s1 = −0.05) the model lacks: times, states, the brake's slip level, the torque per unit of
    pf_c1 and pf_s1 (N m) and the lower disc's residual torque (N m)."""
    import numpy as np

    from drillgym.configurations import N_STATE

    p = RigParams()
    t = np.arange(0, 40.0, 1 / 250)
    wl = 2.0 + 0.8 * np.sin(0.7 * t)
    S = np.zeros((t.size, N_STATE))
    S[:, 1] = np.cumsum(wl) / 250
    S[:, 0] = S[:, 1] - 0.3
    S[:, 2] = S[:, 3] = wl
    level = p.Tc + (p.Ts - p.Tc) * np.exp(-((wl / p.ws) ** p.delta))  # the brake's slip torque
    per_unit = np.column_stack([level * np.cos(S[:, 1]), level * np.sin(S[:, 1])])  # pf_c1, pf_s1 per unit
    tau_l = -per_unit @ np.array([0.12, -0.05]) + 0.002 * rng.standard_normal(t.size)  # the torque it adds
    return t, S, level, per_unit, tau_l


def test_a_residual_a_library_effect_explains_is_answered_by_the_library_effect():
    """A lower-disc torque that is a position friction: discovery's terms explain it (sign(ωl) cos θl), and so do
    the library effect's own columns regressed beside them; the answer is the library effect, not a file.  With
    columns of a library effect that does not explain it (a drift), the candidate stands."""
    import numpy as np

    from drillgym.diagnosis.discovery import find_candidate
    from drillgym.diagnosis.library_columns import LIBRARY_SHARE, library_answer
    from drillgym.diagnosis.sparse import ResidualTorque

    rng = np.random.default_rng(4)
    p = RigParams()
    t, S, level, per_unit, tau_l = _position_friction_residual(rng)
    rt = ResidualTorque(t, 0.002 * rng.standard_normal(t.size), tau_l, S, np.ones(t.size, bool))
    zeros = np.zeros_like(per_unit)
    position = np.vstack([zeros, -per_unit])  # upper disc's rows, then the lower's: the torque per unit
    drift = np.vstack([zeros[:, :1], -(level * t)[:, None]])
    found = find_candidate(
        rt, np.zeros(t.size), p.Ju, p.Jl, library={"position_friction": position, "friction_drift": drift}
    )
    assert found is not None and found.group == "lower_friction", found
    assert found.rest["library:position_friction"] >= LIBRARY_SHARE * found.explained, found.rest
    answer = library_answer(found)
    assert answer is not None and answer.effect == "position_friction", found.rest
    assert "position_friction" in answer.line() and "held in the model" in answer.line()
    alone = find_candidate(rt, np.zeros(t.size), p.Ju, p.Jl, library={"friction_drift": drift})
    assert alone.rest["library:friction_drift"] < 0.2 and library_answer(alone) is None, alone.rest


def test_a_library_effect_on_the_other_disc_is_named_beside_a_candidate_not_for_it():
    """A cogging torque on the motor's disc and a position friction on the brake's at once: the library's position
    friction explains the lower disc's residual, not the upper disc's terms; it is no answer to the upper candidate
    (which would have removed the cogging's file) but is named beside it, to be fitted with it.  The lower disc's
    candidate has the library effect as its answer and nothing beside it."""
    import numpy as np

    from drillgym.diagnosis.discovery import find_candidate
    from drillgym.diagnosis.library_columns import library_answer
    from drillgym.diagnosis.sparse import ResidualTorque

    rng = np.random.default_rng(5)
    p = RigParams()
    t, S, _, per_unit, tau_l = _position_friction_residual(rng)
    tau_u = -0.1 * np.sin(6.0 * S[:, 0] + 0.4) + 0.002 * rng.standard_normal(t.size)
    rt = ResidualTorque(t, tau_u, tau_l, S, np.ones(t.size, bool))
    library = {"position_friction": np.vstack([np.zeros_like(per_unit), -per_unit])}
    upper = find_candidate(rt, np.zeros(t.size), p.Ju, p.Jl, library=library)
    assert upper is not None and upper.group == "upper_force" and upper.explained > 0.9, upper
    assert "library:position_friction" not in upper.rest and library_answer(upper) is None, upper.rest
    assert upper.beside == ("position_friction",)
    assert "position_friction" in upper.found_line() and upper.to_json()["beside"] == ["position_friction"]
    lower = find_candidate(rt, np.zeros(t.size), p.Ju, p.Jl, library=library, only=("lower_friction",))
    assert library_answer(lower).effect == "position_friction" and lower.beside == (), (lower.rest, lower.beside)
