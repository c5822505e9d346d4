"""`drillgym rig run --policy` runs what `drillgym train` writes: the kept learned policy on the emulated rig."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drillgym.io import read_timeseries
from hw.emulator import RigEmulator
from hw.firmware import FirmwareConfig

ROOT = Path(__file__).resolve().parents[1]
LEARNED = ROOT / "agents" / "policies" / "torsional_motor_learned_nominal"
SWITCHED = ROOT / "agents" / "policies" / "torsional_motor_learned"  # the kept learned policy (two networks)
pytestmark = pytest.mark.xdist_group("rig-realtime")  # with tests/test_hw_cli.py: one real-time host at a time
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def _run(*args: str, timeout: float = 240) -> tuple[int, str, str]:
    p = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, env=ENV, timeout=timeout
    )
    return p.returncode, p.stdout, p.stderr


def test_what_train_writes_is_taken_as_a_trained_agent(tmp_path) -> None:
    from hw.commands.rig_ops import trained_agent
    from hw.runner import LinearPolicy

    assert all(
        trained_agent(p)
        for p in (LEARNED, LEARNED / "policy.npz", LEARNED / "model.zip", SWITCHED, SWITCHED / "policy.npz")
    )
    LinearPolicy(np.zeros((1, 7)), np.zeros(1)).save(tmp_path / "linear.npz")
    assert not trained_agent(tmp_path / "linear.npz")  # a bare W, b policy stays a linear policy


@pytest.mark.parametrize("policy", [LEARNED / "policy.npz", SWITCHED / "policy.npz"], ids=["network", "switched"])
def test_kept_learned_policy_runs_on_the_emulated_rig(tmp_path, policy: Path) -> None:
    rec = tmp_path / "run.csv"
    # behaviour, not timing: a relaxed watchdog (the host's reply timeout follows it, up to 1 s) for a loaded machine
    with RigEmulator("torsional", dt=5e-3, firmware=FirmwareConfig(watchdog_s=2.0)) as emu:
        code, out, err = _run(
            "rig",
            "run",
            "--port",
            emu.port,
            "--policy",
            str(policy),
            "--omega-ref",
            "4.0",
            "--duration",
            "1.0",
            "--record",
            str(rec),
            "--no-realtime",
        )
    assert code == 0, (out, err)
    ts = read_timeseries(rec)
    u = ts.u[:-1]  # a row's u applies from its time on; the last row: 0 V after the episode
    assert len(u) >= 90 and np.all(np.abs(u) <= 5.0)
    assert np.ptp(u) > 0.0 or abs(u[0]) > 0.0  # the network answers the encoder: it drives the motor
    assert ts.theta_u[-1] - ts.theta_u[0] > 0.05  # the upper disc turns forward toward the 4 rad/s target
