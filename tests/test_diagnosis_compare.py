"""Compare (where the model fails), the sparse data-driven term, and the CLI commands."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from drillgym import RigParams
from drillgym.cli import app
from drillgym.diagnosis.compare import compare, write_compare
from drillgym.diagnosis.sparse import residual_torques, sparse_residual_model
from drillgym.errors import DataFormatError
from drillgym.identification import prepare_experiment
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.io import write_timeseries
from drillgym.model import Model


@pytest.fixture(scope="module")
def pf_data():
    return synthetic_measurement(
        "torsional",
        duration=20.0,
        rate_hz=250.0,
        offset=1.0,
        seed=1,
        effects=["position_friction"],
        effect_params={"pf_c1": 0.3 * np.cos(1.0), "pf_s1": 0.3 * np.sin(1.0)},
    )


def test_compare_names_angle_dependence(pf_data, tmp_path):
    comp = compare(pf_data, segment_s=4.0)
    assert set(comp.metrics) == {"theta_u", "theta_l", "alpha"}
    assert comp.metrics["theta_l"]["rms"] > 0.01
    assert any("angle" in f for f in comp.findings), comp.findings
    m = np.array([d["mean"] for d in comp.by_angle])
    assert m.max() - m.min() > 0.02  # N m: friction varies over a revolution
    paths = write_compare(comp, tmp_path)
    assert all(p.exists() for p in paths)
    assert json.loads((tmp_path / "compare.json").read_text())["findings"] == comp.findings


def test_compare_exact_model_free_run():
    ts = synthetic_measurement("upper", duration=10.0, rate_hz=250.0, offset=0.5, seed=2)
    comp = compare(ts)
    assert comp.metrics["theta_u"]["r2"] > 0.99999
    assert comp.segment_s is None


def test_compare_claims_failures_only_above_noise(pf_data, tmp_path):
    exact = synthetic_measurement("torsional", duration=12.0, rate_hz=250.0, offset=1.0, seed=2)
    comp = compare(exact, segment_s=4.0)
    assert len(comp.findings) == 1 and "within the measurement noise" in comp.findings[0], comp.findings
    paths = write_compare(comp, tmp_path / "exact")
    assert not (tmp_path / "exact" / "bins.png").exists()  # no empty panels
    comp = compare(pf_data, segment_s=4.0)  # a real failure: binned against speed, angle and twist
    assert comp.by_alpha and comp.by_speed and comp.by_angle
    assert all(comp.metrics[c]["rms"] > 3 * comp.noise[c] for c in ("theta_l", "alpha"))
    paths = write_compare(comp, tmp_path / "pf")
    assert (tmp_path / "pf" / "bins.png") in paths


def test_sparse_term_for_position_friction_and_string_damping(pf_data):
    term = sparse_residual_model(residual_torques(prepare_experiment(pf_data), RigParams()))
    assert {"sign(ωl) cos θl", "sign(ωl) sin θl"} & set(term.terms), term.expression()
    ts = synthetic_measurement(
        "torsional",
        duration=20.0,
        rate_hz=250.0,
        offset=1.0,
        seed=1,
        effects=["string_damping"],
        effect_params={"dtheta": 0.01},
    )
    term = sparse_residual_model(residual_torques(prepare_experiment(ts), RigParams()))
    assert term.terms.get("α̇", 0.0) == pytest.approx(-0.01, rel=0.3), term.expression()
    assert "α̇" in term.expression()


def test_prepare_experiment_rates_and_errors(tmp_path):
    ts = synthetic_measurement("torsional", duration=5.0, rate_hz=500.0, offset=2.0, seed=3)
    ex = prepare_experiment(ts, compare_rate_hz=100.0)
    assert ex.fs == 100.0 and ex.n == 501
    w = ex.rates["omega_l"]
    assert np.abs(w).max() > 1.0 and np.mean(w == 0.0) > 0.05  # slips, and stuck samples are exactly 0
    ts.meta.pop("configuration")
    with pytest.raises(ValueError, match="no configuration"):
        prepare_experiment(ts)
    del ts.columns["theta_l"]
    with pytest.raises(DataFormatError, match="theta_l"):
        prepare_experiment(ts, "torsional")


def test_cli_diagnose_identify_signal(tmp_path):
    ts = synthetic_measurement(
        "torsional",
        duration=8.0,
        rate_hz=250.0,
        offset=1.0,
        seed=1,
        effects=["string_damping"],
        effect_params={"dtheta": 0.01},
    )
    data = write_timeseries(tmp_path / "run.csv", ts)
    runner = CliRunner()
    # the CLI chain (the selection itself, base refit and discovery, is tested in test_diagnosis_selection.py)
    r = runner.invoke(app, ["diagnose", str(data), "--json", "--fixed-base", "--no-sparse"])
    assert r.exit_code == 0, r.output
    js = json.loads(r.output)
    assert js["ranking"][0]["effect"] == "string_damping" and js["selected"] == ["string_damping"]
    out = tmp_path / "p.json"
    r = runner.invoke(
        app,
        [
            "identify",
            str(data),
            "--config",
            "torsional",
            "--add-effect",
            "string_damping",
            "--json",
            "--out",
            str(out),
            "--report",
            str(tmp_path / "rep"),
        ],
    )
    assert r.exit_code == 0, r.output
    js = json.loads(r.output)
    assert js["r2_after"]["alpha"] > js["r2_before"]["alpha"]
    model = Model.load(out)
    assert model.specs == ["string_damping"] and model.values["dtheta"] == pytest.approx(0.01, rel=0.05)
    assert js["fitted"]["dtheta"] == model.values["dtheta"] and js["effects"][0]["name"] == "string_damping"
    assert "The error falling" in (tmp_path / "rep" / "report.md").read_text()
    r = runner.invoke(app, ["compare", str(data), "--segment", "4", "--out", str(tmp_path / "cmp")])
    assert r.exit_code == 0 and (tmp_path / "cmp" / "report.txt").exists()
    r = runner.invoke(app, ["signal", str(tmp_path / "s.csv"), "--kind", "sum_of_sines", "--duration", "5"])
    assert r.exit_code == 0 and (tmp_path / "s.csv").read_text().count("\n") == 5003  # meta, header, 5001 rows
    r = runner.invoke(app, ["diagnose", str(tmp_path / "missing.csv")])
    assert isinstance(r.exception, DataFormatError)
    r = runner.invoke(app, ["identify", str(data), "--add-effect", "bogus", "--out", str(out)])
    assert isinstance(r.exception, ValueError) and "bogus" in str(r.exception)


@pytest.mark.parametrize("segment_s", [0.0, float("nan"), float("inf"), "4"])
def test_compare_refuses_a_segment_that_is_not_a_positive_time(segment_s):
    from drillgym.errors import InputError

    ts = synthetic_measurement("upper", duration=2.0, rate_hz=100.0)
    with pytest.raises(InputError, match=r"^segment_s must be a (positive )?number of seconds"):
        compare(ts, segment_s=segment_s)


def test_compare_takes_a_negative_segment_as_the_configurations_default_as_refit_and_diagnose_do():
    ts = synthetic_measurement("upper", duration=20.0, rate_hz=100.0)
    assert compare(ts, segment_s=-1.0).segment_s == 8.0


def test_compare_json_names_the_signal_path_and_why_a_statistic_is_missing(tmp_path):
    from drillgym.io import TimeSeries, loads_strict

    t = np.arange(300) * 0.01
    still = TimeSeries(
        {"t": t, "u": np.zeros_like(t), "theta_u": np.zeros_like(t)}, {"configuration": "upper"}, "still"
    )
    comp = compare(still, effects=["input_delay", "motor_lag"], effect_params={"delay": 0.02, "tau_m": 0.03})
    write_compare(comp, tmp_path)
    data = loads_strict((tmp_path / "compare.json").read_text(encoding="utf-8"))
    assert data["signal_path"] == ["input_delay", "motor_lag"]
    assert data["metrics"]["theta_u"]["r2"] is None  # no variance: R² undefined
    why = "metrics.theta_u.r2: not computed because the measured theta_u is constant (R² divides by its variance)"
    assert data["warnings"] == [why]


@pytest.mark.parametrize("seed", [0, 1])
def test_the_exact_model_compares_at_the_noise_from_a_start_at_rest(seed):
    """A recording that starts at rest with a step already applied: the speed estimate at its first sample is
    one-sided (the smoothing fit extrapolated to its edge) and may be corrected by as much as it reads, so the
    exact model's first segment is not reported as a misfit (it was 12 noise units on θu for one of these)."""
    ts = synthetic_measurement(
        "torsional", duration=12.0, rate_hz=500.0, signal="steps", offset=1.2, amplitude=1.5, seed=seed
    )
    comp = compare(ts, RigParams(), segment_s=4.0)
    ratios = {c: m["rms"] / comp.noise[c] for c, m in comp.metrics.items()}
    assert max(ratios.values()) < 2.0, ratios
    assert comp.windows[0]["theta_u"] < 2.0 * comp.noise["theta_u"]


def test_the_exact_model_compares_at_the_noise_of_a_reading_with_noise_beyond_its_counts():
    """White noise added after the count (0.3 mrad on 0.8 mrad counts): the readings lie on no lattice of counts,
    and the noise units are their scatter (the count's rounding and the noise together), so the exact model is not
    reported as a misfit (it read tens of noise units when the floor of 0.1 mrad was taken for the noise)."""
    from drillgym.io import TimeSeries

    ts = synthetic_measurement("torsional", duration=12.0, rate_hz=500.0, signal="steps", offset=1.2, amplitude=1.5)
    rng = np.random.default_rng(5)
    cols = dict(ts.columns)
    for c in ("theta_u", "theta_l"):
        cols[c] = np.asarray(cols[c]) + rng.normal(0.0, 3e-4, len(cols[c]))
    noisy = TimeSeries(cols, dict(ts.meta), "<noisy>")
    comp = compare(noisy, RigParams(), segment_s=4.0)
    expected = np.hypot(3e-4, 2 * np.pi / 8000 / np.sqrt(12.0))
    assert comp.noise["theta_u"] == pytest.approx(expected, rel=0.2)
    ratios = {c: m["rms"] / comp.noise[c] for c, m in comp.metrics.items()}
    assert max(ratios.values()) < 2.0, ratios
