"""`drillgym rig tune` against the emulator: the identified model file and what a safety stop leaves."""

from __future__ import annotations

import json

import pytest
from test_hw_cli import run

from drillgym import RigParams
from drillgym.model import Model
from hw.emulator import RigEmulator
from hw.firmware import FirmwareConfig
from hw.safety import SafetyLimits

pytestmark = pytest.mark.xdist_group("rig-realtime")

HIDDEN = RigParams().scaled(km=1.04, bu=0.94, Jl=1.05)


def test_tune_identifies_a_hidden_lag_and_mismatch_into_a_model_file(tmp_path):
    model, rec = tmp_path / "model.json", tmp_path / "excite.csv"
    with RigEmulator("torsional", HIDDEN, effects=["motor_lag"], effect_params={"tau_m": 0.03}, dt=2e-3) as e:
        code, out, err = run(
            "rig", "tune", "--port", e.port, "--model-out", str(model), "--record", str(rec),
            "--duration", "15", "--control-ms", "2", timeout=300,
        )  # fmt: skip
    assert code == 0, (out, err)
    mf = Model.load(model)
    assert "motor_lag" in [str(s) for s in mf.specs]
    assert mf.values["tau_m"] == pytest.approx(0.03, rel=0.25)
    assert mf.params.km == pytest.approx(HIDDEN.km, rel=0.015)
    assert mf.params.Jl == pytest.approx(HIDDEN.Jl, rel=0.02)
    assert "km" in json.loads(model.read_text())["std"]  # the margin check needs it
    assert "tolerates" in out and f"model: {model}" in out
    assert rec.is_file()


def test_tune_safety_stop_keeps_the_recording_and_writes_no_model(tmp_path):
    model, rec = tmp_path / "model.json", tmp_path / "excite.csv"
    fw = FirmwareConfig(limits=SafetyLimits(max_speed=0.5))
    with RigEmulator("torsional", firmware=fw, dt=5e-3) as e:
        code, out, err = run(
            "rig", "tune", "--port", e.port, "--model-out", str(model), "--record", str(rec), "--duration", "10",
            "--control-ms", "10",
        )  # fmt: skip
    assert code == 3 and err.count("\n") == 1 and "no model written" in err, (out, err)
    assert rec.is_file() and not model.exists()


def test_tune_refuses_a_model_file_of_another_kind_before_moving(tmp_path):
    code, out, err = run("rig", "tune", "--port", "/dev/null", "--model-out", str(tmp_path / "m.txt"))
    assert code == 2 and err.count("\n") == 1 and "--model-out" in err, (out, err)
