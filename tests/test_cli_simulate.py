"""drillgym simulate: writes DATA_FORMAT csv and a figure; user errors exit 2 with one line."""

import subprocess
import sys

import numpy as np

from drillgym.io import read_timeseries


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=120)


def test_simulate_writes_run_and_plot(tmp_path):
    out, png = tmp_path / "run.csv", tmp_path / "run.png"
    res = run_cli("simulate", "--config", "coupled", "--u", "1.0", "--duration", "20", "--out", str(out),
                  "--plot", str(png))
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
    assert "missing parameter" in res.stderr and res.stderr.count("\n") == 1
    res = run_cli("simulate", "--config", "sideways", "--u", "1", "--out", str(tmp_path / "x.csv"))
    assert res.returncode == 2 and "unknown configuration 'sideways'" in res.stderr
