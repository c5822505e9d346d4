"""`rig run --params` reads base parameters only: a model file with effects is refused in one line pointing to
--model (a model is never half-read), a file of base parameters or a model file without effects still reads."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from drillgym import Model, RigParams
from hw.emulator import RigEmulator

pytestmark = pytest.mark.xdist_group("rig-realtime")

ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
}


def run(*args: str) -> tuple[int, str, str]:
    p = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, env=ENV, timeout=180
    )
    return p.returncode, p.stdout, p.stderr


def test_a_model_file_with_effects_given_as_params_is_refused_in_one_line(tmp_path):
    with_effects = Model(RigParams().replace(Ts=0.3), ("motor_lag",), {"tau_m": 0.03}).save(tmp_path / "m.json")
    without = Model(RigParams().replace(Ts=0.3)).save(tmp_path / "base" / "m.json")
    (tmp_path / "p.json").write_text(json.dumps({"Ts": 0.3}))
    with RigEmulator("torsional", dt=5e-3) as emu:
        dry = ("--controller", "observer", "--omega-ref", "3", "--dry-run", "--no-realtime")
        code, out, err = run("rig", "run", "--port", emu.port, "--params", str(with_effects), *dry)
        assert code == 2 and err.count("\n") == 1, (out, err)
        assert "--params" in err and "motor_lag" in err and "--model" in err and "Traceback" not in err
        for ok in (without, tmp_path / "p.json"):
            code, out, err = run("rig", "run", "--port", emu.port, "--params", str(ok), *dry)
            assert code == 0 and "controller observer ready" in out, (out, err)
        assert emu.firmware.commands == 0
