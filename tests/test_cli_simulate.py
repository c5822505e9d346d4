"""drillgym simulate: writes a csv of docs/data_format.md and a figure; user errors exit 2 with one line."""

import subprocess
import sys

import numpy as np

from drillgym.io import read_timeseries


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=120)


def test_simulate_writes_run_and_plot(tmp_path):
    out, png = tmp_path / "run.csv", tmp_path / "run.png"
    res = run_cli(
        "simulate", "--config", "coupled", "--u", "1.0", "--duration", "20", "--out", str(out), "--plot", str(png)
    )
    assert res.returncode == 0, res.stderr
    ts = read_timeseries(out)
    assert ts.configuration.label == "coupled" and len(ts) == 20001
    assert np.ptp(ts.omega_l[5000:]) > 3  # stick-slip at 1 V
    assert png.stat().st_size > 10_000


def test_simulate_from_an_input_file(tmp_path):
    sig = tmp_path / "u.csv"
    sig.write_text("t,u,theta_u\n0,0,0\n1,2,0\n2,2,0\n")
    out = tmp_path / "run.csv"
    res = run_cli("simulate", "--config", "upper", "--input", str(sig), "--duration", "2", "--out", str(out))
    assert res.returncode == 0, res.stderr
    ts = read_timeseries(out)
    assert ts.u[0] == 0.0 and ts.u[-1] == 2.0 and ts.omega_u[-1] > 0


def test_user_errors_exit_2_with_one_line(tmp_path):
    bad = tmp_path / "p.json"
    bad.write_text('{"Ju": -1}')
    res = run_cli("simulate", "--u", "1", "--duration", "1", "--params", str(bad), "--out", str(tmp_path / "x.csv"))
    assert res.returncode == 2
    assert "'Ju' = -1.0 kg m^2 is outside its physical range" in res.stderr and res.stderr.count("\n") == 1
    res = run_cli("simulate", "--config", "sideways", "--u", "1", "--out", str(tmp_path / "x.csv"))
    assert res.returncode == 2 and "unknown configuration 'sideways'" in res.stderr


def _one_line_error(res, *needles):
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    assert res.stderr.startswith("drillgym: error: ") and res.stderr.count("\n") == 1, res.stderr
    for n in needles:
        assert n in res.stderr, res.stderr


def test_voltage_beyond_what_the_reader_accepts_is_refused_and_the_limit_round_trips(tmp_path):
    out = tmp_path / "run.csv"
    _one_line_error(run_cli("simulate", "--u", "1e6", "--duration", "0.1", "--out", str(out)), "--u 1e+06 V", "50 V")
    assert not out.exists()
    res = run_cli("simulate", "--config", "upper", "--u", "-50", "--duration", "0.1", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert read_timeseries(out).u[0] == -50.0  # what the writer accepts, the reader reads


def test_input_file_shorter_than_duration_is_refused_and_its_length_is_the_default(tmp_path):
    sig = tmp_path / "u.csv"
    sig.write_text("t,u\n0,0\n0.5,2\n1.0,2\n")  # covers 1.5 s (the last sample held one interval)
    out = tmp_path / "run.csv"
    _one_line_error(
        run_cli("simulate", "--config", "upper", "--input", str(sig), "--duration", "5", "--out", str(out)),
        "covers 1.5 s, shorter than --duration 5 s",
    )
    res = run_cli("simulate", "--config", "upper", "--input", str(sig), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert read_timeseries(out).t[-1] == 1.5
    late = tmp_path / "late.csv"
    late.write_text("t,u\n1,0\n2,2\n")
    _one_line_error(run_cli("simulate", "--input", str(late), "--out", str(out)), "starts at t = 1 s")


def test_huge_duration_refused_before_allocating(tmp_path):
    res = run_cli("simulate", "--u", "1", "--duration", "1e9", "--out", str(tmp_path / "x.csv"))
    _one_line_error(res, "--duration 1e+09 s", "of memory", "available", "--record-every")
    assert "Traceback" not in res.stderr


def test_free_vibration_takes_alpha0_and_no_voltage(tmp_path):
    out = tmp_path / "fv.csv"
    _one_line_error(
        run_cli("simulate", "--config", "free_vibration", "--duration", "1", "--out", str(out)), "give --alpha0 RAD"
    )
    _one_line_error(
        run_cli("simulate", "--config", "free_vibration", "--u", "1", "--alpha0", "1", "--out", str(out)),
        "leave out --u/--input",
    )
    res = run_cli("simulate", "--config", "free_vibration", "--alpha0", "1.0", "--duration", "2", "--out", str(out))
    assert res.returncode == 0, res.stderr
    ts = read_timeseries(out)
    assert ts.theta_l[0] == 1.0 and np.all(ts.theta_u == 0) and np.ptp(ts.omega_l) > 0.5  # released and swinging
    assert "--alpha0" in run_cli("simulate", "--help").stdout


def test_upper_reports_the_upper_disc(tmp_path):
    res = run_cli("simulate", "--config", "upper", "--u", "1", "--duration", "1", "--out", str(tmp_path / "u.csv"))
    assert res.returncode == 0, res.stderr
    assert "lower disc" not in res.stdout and "omega_l" not in res.stdout
    assert "final omega_u" in res.stdout and "upper disc stuck" in res.stdout


def test_partial_parameter_file(tmp_path):
    p = tmp_path / "p.yaml"
    p.write_text("Ts: 0.35\n")
    out = tmp_path / "run.csv"
    res = run_cli("simulate", "--u", "1", "--duration", "0.5", "--params", str(p), "--out", str(out))
    assert res.returncode == 0, res.stderr
    p.write_text("Ts: 0.35\nTs_typo: 1\n")
    _one_line_error(
        run_cli("simulate", "--u", "1", "--duration", "0.5", "--params", str(p), "--out", str(out)),
        "unknown parameter(s): Ts_typo",
    )
