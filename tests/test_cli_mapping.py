"""Column mapping for recordings: ``--map`` on compare/diagnose/identify, Simulink "structure with time"
logs whose ``signals.values`` has several columns, and CSV columns under other names."""

import subprocess
import sys

import numpy as np
import pytest
import scipy.io

from drillgym import simulate
from drillgym.io import DataFormatError, read_timeseries


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def run():
    return simulate("torsional", u=1.5, duration=3.0, record_every=10)


def _scope(path, tr):
    """A Simulink Scope log, "structure with time": one muxed signal of 3 columns (u, enc upper, enc lower)."""
    vals = np.column_stack([tr.u, tr.theta_u, tr.theta_l])
    scipy.io.savemat(path, {"ScopeData": {"time": tr.t, "signals": {"values": vals, "dimensions": 3, "label": ""}}})
    return path


def test_structure_with_time_several_columns(tmp_path, run):
    path = _scope(tmp_path / "scope.mat", run)
    with pytest.raises(
        DataFormatError, match=r"'scopedata' for column 'u' has 3 columns; choose one: --map u=scopedata:K"
    ):
        read_timeseries(path, "torsional", {"u": "ScopeData"})
    ts = read_timeseries(path, "torsional", {"u": "ScopeData:1", "theta_u": "ScopeData:2", "theta_l": "ScopeData:3"})
    np.testing.assert_array_equal(ts.theta_l, run.theta_l)
    np.testing.assert_array_equal(ts.t, run.t)
    with pytest.raises(DataFormatError, match="mapping names variable 'scopedata:7'"):
        read_timeseries(path, "torsional", {"u": "ScopeData:7"})


def test_structure_with_time_several_signals_labels_and_columns(tmp_path, run):
    sigs = np.array(
        [(run.u.reshape(-1, 1), "u"), (run.theta_u.reshape(-1, 1), "theta_u"), (run.theta_l.reshape(-1, 1), "")],
        dtype=[("values", object), ("label", object)],
    )
    path = tmp_path / "logs.mat"
    scipy.io.savemat(path, {"logs": {"time": run.t, "signals": sigs}})
    with pytest.raises(DataFormatError, match="missing column.*theta_l"):
        read_timeseries(path, "torsional")  # the unlabelled third signal is not guessed
    ts = read_timeseries(path, "torsional", {"theta_l": "logs:3"})  # labels name the others
    np.testing.assert_array_equal(ts.theta_u, run.theta_u)
    np.testing.assert_array_equal(ts.theta_l, run.theta_l)


def test_csv_mapping(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("time,volts,enc1\n0,0,0\n0.1,1,0.01\n")
    ts = read_timeseries(p, "upper", {"t": "time", "u": "volts", "theta_u": "enc1"})
    assert ts.theta_u[1] == 0.01
    with pytest.raises(DataFormatError, match="mapping names column 'enc9' for 'theta_u'"):
        read_timeseries(p, "upper", {"t": "time", "u": "volts", "theta_u": "enc9"})
    with pytest.raises(DataFormatError, match="unknown column"):
        read_timeseries(p, "upper", {"speed": "enc1"})


def test_compare_reads_a_scope_log_through_map(tmp_path, run):
    path = _scope(tmp_path / "scope.mat", run)
    res = run_cli(
        "compare",
        str(path),
        "--config",
        "torsional",
        "--map",
        "u=ScopeData:1",
        "--map",
        "theta_u=ScopeData:2",
        "--map",
        "theta_l=ScopeData:3",
        "--out",
        str(tmp_path / "new" / "cmp"),
    )
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "new" / "cmp" / "report.txt").exists()  # missing directories created
    res = run_cli("compare", str(path), "--config", "torsional", "--out", str(tmp_path / "cmp2"))
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "missing column(s) u, theta_u" in res.stderr
    assert "the file has scopedata, scopedata:1, scopedata:2, scopedata:3: name the columns with --map" in res.stderr


@pytest.mark.parametrize("command", ["compare", "diagnose", "identify"])
def test_bad_map_is_one_line(tmp_path, command, run):
    csv = tmp_path / "r.csv"
    run.to_csv(csv)
    extra = ["--out", str(tmp_path / "p.json")] if command == "identify" else []
    res = run_cli(command, str(csv), "--map", "theta_u", *extra)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "expected COLUMN=NAME" in res.stderr, res.stderr
    res = run_cli(command, str(csv), "--map", "theta_u=enc1", *extra)
    assert res.returncode == 2 and "mapping names column 'enc1' for 'theta_u'" in res.stderr, res.stderr
