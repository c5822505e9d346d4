"""Claims the data can carry: no verdict and no model file from a recording in which nothing turns."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner


@pytest.fixture(scope="module")
def resting(tmp_path_factory):
    """0.2 s of a resting rig under a command far below the breakaway."""
    from drillgym.identification.synthetic import synthetic_measurement
    from drillgym.io import write_timeseries

    ts = synthetic_measurement("torsional", duration=0.2, rate_hz=500.0, offset=0.05, amplitude=0.1, seed=1)
    return write_timeseries(tmp_path_factory.mktemp("rest") / "rest.csv", ts)


@pytest.mark.parametrize("route", ["diagnose", "identify"])
def test_no_verdict_and_no_model_from_a_recording_in_which_nothing_turns(resting, tmp_path, route):
    from bad_inputs import run_cli

    out = tmp_path / "model.json"
    code, stdout, stderr = run_cli(route, resting, "--model-out" if route == "diagnose" else "--out", out)
    assert code == 2, stdout + stderr
    lines = [x for x in (stdout + stderr).splitlines() if x.strip()]
    assert len(lines) == 1 and "cannot tell from this recording" in lines[0] and "would tell" in lines[0]
    assert not out.exists()


def test_compare_says_a_match_at_rest_tells_nothing(resting, tmp_path):
    from drillgym.cli import app

    r = CliRunner().invoke(app, ["compare", str(resting), "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "cannot tell from this recording" in r.output and "within the measurement noise" not in r.output


def test_a_recording_that_turns_carries_a_verdict():
    from drillgym.diagnosis.information import recording_information
    from drillgym.identification.synthetic import synthetic_measurement

    ts = synthetic_measurement("torsional", duration=2.0, rate_hz=250.0, offset=1.0, seed=5)
    assert recording_information(ts).why_not is None
