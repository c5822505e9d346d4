"""The rig emulator's plant runs hidden effects through the same compiled composition as every
other path: its periods match the single-run simulator to 1e-9 (input delay by the kernels' delay
line, no FIFO of its own), its LVDT readings pass through the composition's Measurement effects,
and ``drillgym rig emulate --add-effect/--effect-param`` sets them."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import drillgym
from drillgym.cli import app
from drillgym.commands.plant import plant_from_cli
from hw import protocol as P
from hw.firmware import Firmware

ROOT = Path(__file__).resolve().parents[1]
CUBIC = f"{ROOT / 'examples' / 'effects' / 'string_cubic.py'}:string_cubic"
VENV_BIN = Path(sys.executable).parent
DT = 5e-3  # plant step (s): two steps per 10 ms control period
PERIODS = 300


def _commands(n: int = PERIODS) -> np.ndarray:
    r = np.random.default_rng(3)
    return np.clip(np.repeat(r.uniform(1.0, 4.0, n // 25 + 1), 25)[:n] + r.normal(0.0, 0.1, n), 0.0, 4.5)


def _drive(fw: Firmware, volts: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
    """SET_VOLTAGE once per period (no wall-clock idling): applied voltages, omega_l after each
    period (rad/s), decoded SAMPLEs."""
    applied, wl, samples = [], [], []
    parser = P.FrameParser()
    for k, v in enumerate(volts):
        frames = fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, k & 0xFFFF, P.SetVoltage(float(v)).pack()), now=0.01 * k)
        samples.append(P.decode(parser.feed(frames[0])[0]))
        assert fw.stop_reason is None, fw.stop_reason
        applied.append(fw.volts)
        wl.append(float(fw.sim.omega_l[0]))
    return np.array(applied), np.array(wl), samples


@pytest.mark.parametrize(
    "effects, values",
    [
        (["input_delay"], {"delay": 0.03}),
        (["motor_lag"], {"tau_m": 0.05}),
        ([CUBIC], {"c3": 0.01}),
    ],
)
def test_emulated_plant_matches_the_simulator_with_hidden_effects(effects, values) -> None:
    alpha0 = 0.3
    fw = Firmware("torsional", effects=effects, effect_params=values, dt=DT, alpha0=alpha0)
    applied, wl, _ = _drive(fw, _commands())
    assert np.ptp(applied) > 2.0  # the slew-limited commands varied
    n_sub = fw.n_sub
    traj = drillgym.simulate(
        "torsional",
        u=np.repeat(applied, n_sub),
        duration=len(applied) * n_sub * DT,
        dt=DT,
        alpha0=alpha0,
        effects=effects,
        effect_params=values,
    )
    ref = traj.omega_l[n_sub::n_sub]
    assert np.abs(wl - ref).max() <= 1e-9
    base = Firmware("torsional", dt=DT, alpha0=alpha0)
    _, wl_base, _ = _drive(base, _commands())
    assert np.abs(wl - wl_base).max() > 0.02  # the hidden effect is there
    assert fw.effect_values == values


def test_emulated_lvdts_read_through_measurement_effects() -> None:
    x0, y0, skew = 1e-3, -5e-4, 0.1
    fw = Firmware(
        "coupled",
        effects=["lvdt_offset", "lvdt_skew"],
        effect_params={"lvdt_x0": x0, "lvdt_y0": y0, "lvdt_skew": skew},
        dt=DT,
        alpha0=0.5,
    )
    _, _, samples = _drive(fw, np.full(150, 4.0))
    X, Y = (float(a[0]) for a in fw.sim.lateral_fixed)
    assert abs(X) + abs(Y) > 1e-6  # the disc moved laterally
    lsb = fw.config.lvdt_m_per_lsb
    s = samples[-1]
    assert s.lvdt_x == round((X + x0) / lsb)
    assert s.lvdt_y == round(((Y + y0) * math.cos(skew) + (X + x0) * math.sin(skew)) / lsb)
    cpr = fw.config.counts_per_rev
    assert s.counts_u == math.floor(fw.sim.theta_u[0] * cpr / (2 * math.pi))  # encoders untouched


def test_plant_from_cli_reads_effects_and_names_bad_input(tmp_path) -> None:
    base, comp, values = plant_from_cli(None, ["input_delay", CUBIC], ["delay=0.02", "c3=0.05"])
    assert comp.names == ("input_delay", "string_cubic") and values == {"delay": 0.02, "c3": 0.05}
    with pytest.raises(ValueError, match="no effect added"):
        plant_from_cli(None, None, ["delay=0.02"])
    with pytest.raises(ValueError, match="not a number"):
        plant_from_cli(None, ["input_delay"], ["delay=fast"])
    with pytest.raises(ValueError, match="delay"):
        plant_from_cli(None, ["input_delay"], ["delay=3"])  # above its 0.5 s bound
    res = CliRunner().invoke(app, ["rig", "emulate", "--add-effect", "no_such_effect"])
    assert res.exit_code != 0 and "no_such_effect" in str(res.exception)


def test_rig_emulate_cli_starts_with_hidden_effects(tmp_path) -> None:
    link = tmp_path / "rig"
    proc = subprocess.Popen(
        [
            str(VENV_BIN / "drillgym"),
            "rig",
            "emulate",
            "--port",
            str(link),
            "--dt",
            "0.005",
            "--add-effect",
            "input_delay",
            "--effect-param",
            "delay=0.04",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert "rig emulator (torsional) on /dev/pts/" in line and link.is_symlink(), proc.stderr.read()
        assert "hidden effects: input_delay(delay=0.04)" in line
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    bad = subprocess.run(
        [str(VENV_BIN / "drillgym"), "rig", "emulate", "--effect-param", "delay=0.04"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "--add-effect" in bad.stderr
