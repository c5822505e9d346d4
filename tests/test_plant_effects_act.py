"""The plant of `rig emulate` and `evaluate` (--params FILE, --add-effect) refuses an effect that does not act in its
configuration, as --model does: the plant would run without it while the command names it as hidden."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from drillgym import Model
from drillgym.commands.plant import plant_from_cli
from drillgym.configurations import parse_configuration
from drillgym.errors import InputError

ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
}


@pytest.fixture
def lateral_model(tmp_path) -> Path:
    return Model(effects=("lateral_anisotropy",), values={"dk": 200.0}).save(tmp_path / "m" / "model.json")


def test_the_plant_refuses_an_effect_its_configuration_does_not_run(lateral_model):
    torsional, coupled = parse_configuration("torsional"), parse_configuration("coupled")
    with pytest.raises(InputError, match=r"^--params .*model\.json: the model's effects lateral_anisotropy: the "):
        plant_from_cli(lateral_model, None, None, configs=(coupled, torsional))
    with pytest.raises(InputError, match=r"^--add-effect lateral_anisotropy: the effect does not act in the torsional"):
        plant_from_cli(None, ["lateral_anisotropy"], None, configs=(torsional,))
    _, comp, values = plant_from_cli(lateral_model, None, None, configs=(coupled,))
    assert comp.names == ("lateral_anisotropy",) and values["dk"] == 200.0
    _, comp, _ = plant_from_cli(lateral_model, None, None)  # no configuration given: nothing to check
    assert comp.names == ("lateral_anisotropy",)


def test_rig_emulate_refuses_a_model_file_whose_effect_its_configuration_does_not_run(lateral_model):
    args = ["rig", "emulate", "--config", "torsional", "--params", str(lateral_model), "--no-realtime"]
    p = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, env=ENV, timeout=60
    )
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert "lateral_anisotropy" in p.stderr and "does not act in the torsional configuration" in p.stderr
