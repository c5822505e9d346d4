"""One recording, four routes, one model file: every route to a model is :func:`drillgym.identify`."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.xdist_group("identify_routes")  # one recording's compiled models, one worker


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """6 s of a simulated torsional recording (250 Hz) whose motor lags by 40 ms."""
    from drillgym.identification.synthetic import synthetic_measurement
    from drillgym.io import write_timeseries

    ts = synthetic_measurement(
        "torsional",
        duration=6.0,
        rate_hz=250.0,
        offset=1.0,
        seed=5,
        effects=["motor_lag"],
        effect_params={"tau_m": 0.04},
    )
    return write_timeseries(tmp_path_factory.mktemp("rec") / "lag.csv", ts)


@pytest.fixture(scope="module")
def routes(recording, tmp_path_factory):
    """The model file each route writes for the recording."""
    from typer.testing import CliRunner

    from controllers.evaluation.identify import identify_plant
    from drillgym.cli import app
    from drillgym.io import read_timeseries
    from hw.commands.tune import _identify_and_write

    out = tmp_path_factory.mktemp("routes")
    runner = CliRunner()
    files = {}
    files["diagnose"] = out / "diagnose" / "model.json"
    r = runner.invoke(app, ["diagnose", str(recording), "--model-out", str(files["diagnose"])])
    assert r.exit_code == 0, r.output
    files["identify"] = out / "identify" / "model.json"
    r = runner.invoke(app, ["identify", str(recording), "--out", str(files["identify"])])
    assert r.exit_code == 0, r.output
    files["harness"] = out / "harness" / "model.json"
    identify_plant(read_timeseries(recording), []).model.save(files["harness"])
    files["rig tune"] = out / "tune" / "model.json"
    lines: list[str] = []
    _identify_and_write(recording, files["rig tune"], lines.append)
    return files


@pytest.mark.slow
def test_every_route_writes_the_same_model_file(routes):
    texts = {route: path.read_bytes() for route, path in routes.items()}
    assert len(set(texts.values())) == 1, {r: json.loads(t)["effects"] for r, t in texts.items()}


def test_the_model_file_is_the_identified_model(routes, recording):
    from drillgym import Encoders, Model

    m = Model.load(routes["identify"])
    assert "motor_lag" in m.names
    assert m.values["tau_m"] == pytest.approx(0.04, rel=0.1)
    assert m.provenance.route == "identify" and m.provenance.recording == recording.name
    assert len(m.provenance.recording_sha256) == 64
    assert m.encoders == Encoders(8000, 0.0)  # the recording's encoders: whole counts of 8000 per revolution
    from drillgym import identify

    assert "  encoders: 8000 counts/rev (told to the controllers built on it)" in identify(recording).lines()
    import controllers

    built = controllers.make("lqg-2enc", model=routes["identify"], omega_ref=2.0)
    assert built.design.counts == 8000 and built.effects == m  # told the model's encoders, the model read once
    assert controllers.make("lqg-2enc", model=m, counts_per_rev=2048).design.counts == 2048  # the caller's first


def test_compare_with_the_model_shows_the_error_fall(routes, recording, tmp_path):
    from typer.testing import CliRunner

    from drillgym.cli import app

    r = CliRunner().invoke(
        app, ["compare", str(recording), "--model", str(routes["identify"]), "--out", str(tmp_path), "--json"]
    )
    assert r.exit_code == 0, r.output
    chans = json.loads(r.output)["channels"]
    assert all(np.isfinite(c["model_to_noise"]) for c in chans.values())
    assert all(c["model_rms"] < c["nominal_rms"] for c in chans.values())
    assert (tmp_path / "nominal_vs_model.png").is_file() and (tmp_path / "compare_models.json").is_file()
