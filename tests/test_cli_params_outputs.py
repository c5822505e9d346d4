"""``drillgym params`` and the one rule for output paths (missing directories are created, said in --help)."""

import json
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from drillgym.cli import app
from drillgym.params import PARAM_INFO, RigParams


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=120)


def test_params_prints_every_parameter_with_unit_and_source():
    res = run_cli("params")
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stdout.splitlines() if not ln.startswith("#")]
    assert len(lines) == len(PARAM_INFO)
    assert "Ts: 0.2781  # N m; rebuilt table 3.7; brake static friction" in res.stdout


@pytest.mark.parametrize("name", ["p.yaml", "p.json"])
def test_params_out_round_trips_and_partial_files_complete(tmp_path, name):
    out = tmp_path / "new" / "dir" / name
    res = run_cli("params", "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert RigParams.from_file(out) == RigParams()
    if name.endswith(".json"):
        assert json.loads(out.read_text())["units"]["Ts"] == "N m"
    part = tmp_path / "part.yaml"
    part.write_text("Ts: 0.35\nb: 31.0\n")
    res = run_cli("params", "--params", str(part), "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert RigParams.from_file(out) == RigParams().replace(Ts=0.35, b=31.0)
    part.write_text("Ts: 0.35\nTx: 1\n")
    res = run_cli("params", "--params", str(part))
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "unknown parameter(s): Tx" in res.stderr


def test_params_refuses_other_suffixes(tmp_path):
    res = run_cli("params", "--out", str(tmp_path / "p.txt"))
    assert res.returncode == 2 and "must end in .json, .yaml or .yml" in res.stderr


def test_one_rule_for_output_paths(tmp_path):
    """simulate --out / --plot, signal OUT and params --out create missing directories (as rig run --record
    does, tests/test_hw_cli.py); a file in the way is refused in one line; every such option says so."""
    res = run_cli(
        "simulate",
        "--config",
        "upper",
        "--u",
        "1",
        "--duration",
        "0.2",
        "--out",
        str(tmp_path / "a" / "b" / "run.csv"),
        "--plot",
        str(tmp_path / "c" / "run.png"),
    )
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "a" / "b" / "run.csv").exists() and (tmp_path / "c" / "run.png").exists()
    res = run_cli("signal", str(tmp_path / "d" / "u.csv"), "--duration", "1")
    assert res.returncode == 0 and (tmp_path / "d" / "u.csv").exists(), res.stderr
    (tmp_path / "file").write_text("")
    res = run_cli("simulate", "--u", "1", "--duration", "0.2", "--out", str(tmp_path / "file" / "run.csv"))
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "is a file, not a directory" in res.stderr
    for command, option in [
        ("simulate", "--out"),
        ("simulate", "--plot"),
        ("params", "--out"),
        ("signal", "OUT"),
        ("compare", "--out"),
        ("identify", "--out"),
        ("identify", "--report"),
        ("identify-staged", "--out"),
        ("bifurcation", "--out"),
        ("rig run", "--record"),
    ]:
        res = CliRunner().invoke(app, [*command.split(), "--help"], terminal_width=200)
        assert "missing directories are created" in " ".join(res.output.replace("│", " ").split()), (command, option)
