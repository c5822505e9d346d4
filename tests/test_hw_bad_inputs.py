"""Bad inputs to the hardware twin, refused before any port is opened or file written: every option of
`drillgym rig run`, `rig emulate` and `rig estop` with bad values, the recording path (also in --dry-run),
a file that is not a policy, a disk error while recording, and the Python API refusing what the CLI refuses."""

from __future__ import annotations

import errno
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drillgym.errors import InputError, MissingFileError, OutputPathError, SafetyError
from hw.checks import check_port, check_record_path, number
from hw.client import RigClient
from hw.commands.rig import _check_emulate_options, _check_run_options
from hw.emulator import RigEmulator
from hw.env import HardwareEnv
from hw.firmware import FirmwareConfig
from hw.recording import EpisodeRecorder, RecordingError
from hw.runner import LinearPolicy, load_policy, make_controller

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
DEVICE = "/dev/null"  # a character device: passes the port check, so the option under test is what is refused


def _cli(*args: str) -> tuple[int, str]:
    p = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, env=ENV, timeout=120
    )
    return p.returncode, p.stderr.strip()


def _run_opts(**kw):
    args = dict(
        port=DEVICE, duration=10.0, record=Path("rig_run.csv"), config="torsional", observation="sensors",
        omega_ref=None, control_ms=10.0, seed=0, reply_timeout_ms=None, reconnect=0, wait=2.0,
    )  # fmt: skip
    args.update(kw)
    return _check_run_options(**args)


def _emulate_opts(**kw):
    args = dict(
        port=None, config="torsional", counts_per_rev=8000, lvdt_noise=3e-6, latency_ms=0.0, jitter_ms=0.0,
        period_ms=10.0, watchdog_ms=100.0, dt=1e-3, alpha0=0.0, seed=0,
    )  # fmt: skip
    args.update(kw)
    _check_emulate_options(**args)


NAN, INF = math.nan, math.inf


@pytest.mark.parametrize(
    "option, value",
    [
        ("duration", -1.0), ("duration", 0.0), ("duration", NAN), ("duration", INF), ("duration", 1e-3),
        ("control_ms", 0.0), ("control_ms", -2.0), ("control_ms", NAN), ("control_ms", 1e9),
        ("omega_ref", -1.0), ("omega_ref", 0.0), ("omega_ref", NAN), ("omega_ref", 1e9),
        ("seed", -1), ("seed", 2**40),
        ("reply_timeout_ms", 0.0), ("reply_timeout_ms", NAN), ("reply_timeout_ms", 5000.0),
        ("reconnect", -1), ("wait", -1.0), ("wait", INF), ("wait", NAN),
        ("config", "bogus"), ("observation", "bogus"),
    ],
)  # fmt: skip
def test_rig_run_refuses_each_bad_option_naming_it(option, value):
    with pytest.raises(InputError) as exc:
        _run_opts(**{option: value})
    flag = {"wait": "--reconnect-wait"}.get(option, "--" + option.replace("_", "-"))
    if option == "duration" and value == 1e-3:
        flag = "--duration"  # shorter than one control period
    msg = str(exc.value)
    assert flag in msg and "\n" not in msg and "np.float" not in msg


@pytest.mark.parametrize(
    "option, value",
    [
        ("config", "bogus"), ("counts_per_rev", 0), ("counts_per_rev", -5), ("counts_per_rev", 2**40),
        ("lvdt_noise", -1.0), ("lvdt_noise", NAN), ("lvdt_noise", INF),
        ("latency_ms", -1.0), ("latency_ms", NAN), ("latency_ms", INF), ("jitter_ms", NAN), ("jitter_ms", 1e12),
        ("period_ms", 0.0), ("period_ms", NAN), ("period_ms", 2.5), ("period_ms", 1e12),
        ("watchdog_ms", 0.0), ("watchdog_ms", NAN), ("watchdog_ms", 1e6), ("watchdog_ms", 0.5),
        ("dt", 0.0), ("dt", -1.0), ("dt", NAN), ("dt", 1.0), ("dt", 3e-4),
        ("alpha0", NAN), ("alpha0", 1e9), ("seed", -1),
    ],
)  # fmt: skip
def test_rig_emulate_refuses_each_bad_option_naming_it(option, value):
    with pytest.raises(InputError) as exc:
        _emulate_opts(**{option: value})
    msg = str(exc.value)
    named = "--period-ms" if (option, value) in (("period_ms", 2.5), ("dt", 3e-4)) else "--" + option.replace("_", "-")
    assert named in msg and "\n" not in msg


def test_valid_options_pass():
    opts = _run_opts(omega_ref=1.0, control_ms=2.0, reply_timeout_ms=100.0)
    assert opts["control_dt"] == pytest.approx(2e-3) and opts["omega_ref"] == 1.0
    _emulate_opts(period_ms=2.5, dt=5e-4, latency_ms=1.0, jitter_ms=0.5, watchdog_ms=2000.0, alpha0=1.0)


def test_emulate_link_path_is_checked_before_anything(tmp_path):
    (tmp_path / "data.csv").write_text("t,u\n0,0\n")
    (tmp_path / "file").write_text("x")
    for port, what in [
        (tmp_path / "data.csv", "exists"),
        (tmp_path, "exists"),
        (tmp_path / "file" / "rig", "not a directory"),
        (Path("/proc/drillgym-rig"), "cannot create"),
    ]:
        with pytest.raises(OutputPathError, match=what) as exc:
            _emulate_opts(port=port)
        assert "--port" in str(exc.value)
    assert (tmp_path / "data.csv").read_text() == "t,u\n0,0\n"
    _emulate_opts(port=tmp_path / "new" / "rig")  # missing folders are fine (created at start)
    assert not (tmp_path / "new").exists()  # ... but not by the check


def test_record_path_checks(tmp_path):
    os.mkfifo(tmp_path / "pipe.csv")
    (tmp_path / "plain").write_text("x")
    (tmp_path / "dir.csv").mkdir()
    bad = {
        "/proc/x.csv": "cannot create",
        str(tmp_path / "pipe.csv"): "a pipe",
        str(tmp_path / "dir.csv"): "a directory",
        str(tmp_path / "plain"): "is a file",
        str(tmp_path / "plain" / "x.csv"): "not a directory",
        "/dev/null": "a device",
        "": "empty",
    }
    for path, what in bad.items():
        with pytest.raises(OutputPathError, match=what) as exc:
            check_record_path(path)
        assert str(exc.value).startswith("--record")
    for ok in (tmp_path / "run.csv", tmp_path / "deep" / "run.csv", tmp_path, tmp_path / "episodes"):
        assert check_record_path(ok) == ok
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.csv", "pipe.csv", "plain"]  # nothing created


def test_port_checks(tmp_path):
    (tmp_path / "plain").write_text("x")
    with pytest.raises(MissingFileError, match="does not exist"):
        check_port(str(tmp_path / "none"))
    for p, what in [(tmp_path, "a directory"), (tmp_path / "plain", "is a file"), ("", "empty")]:
        with pytest.raises(InputError, match=what):
            check_port(str(p) if p != "" else p)
    assert check_port("loop://") == "loop://" and check_port(DEVICE) == DEVICE


def test_dry_run_refuses_an_unwritable_record_path_before_the_port():
    # the port does not even exist: the recording path is refused first
    code, err = _cli("rig", "run", "--port", DEVICE, "--controller", "const:1", "--record", "/proc/x.csv", "--dry-run")
    assert code == 2 and err.count("\n") == 0 and "--record /proc/x.csv" in err


def test_garbage_policy_is_one_line_naming_the_file(tmp_path):
    bad = tmp_path / "garbage.npz"
    bad.write_bytes(b"this is not numpy")
    code, err = _cli("rig", "run", "--port", DEVICE, "--policy", str(bad), "--dry-run")
    assert code == 2 and err.count("\n") == 0, err
    assert f"--policy {bad}: not a policy file" in err and "pickle" not in err
    code, err = _cli("rig", "run", "--port", DEVICE, "--policy", str(tmp_path / "none.npz"), "--dry-run")
    assert code == 2 and "--policy" in err and "does not exist" in err
    with pytest.raises(InputError, match="numpy could not read it") as exc:
        load_policy(bad)  # the Python API says the same, without numpy's pickle advice
    assert "pickle" not in str(exc.value)


def test_constant_controller_refuses_a_non_finite_voltage():
    for spec in ("const:nan", "const:inf", "const:-inf"):
        with pytest.raises(InputError, match="finite"):
            make_controller(spec, "torsional", None, 0.01)
    assert make_controller("const:-2.5", "torsional", None, 0.01).volts == -2.5


def test_python_api_refuses_what_the_cli_refuses(tmp_path):
    for kw, what in [
        ({"record": "/proc/x.csv"}, "cannot create"),
        ({"reply_timeout": 0.0}, "reply_timeout"),
        ({"reply_timeout": math.nan}, "reply_timeout"),
        ({"rest_time": -1.0}, "rest_time"),
        ({"rest_time": 1.0, "rest_timeout": 0.5}, "rest_timeout"),
        ({"lvdt_cutoff_hz": math.inf}, "lvdt_cutoff_hz"),
        ({"lvdt_cutoff_hz": 80.0}, "lvdt_cutoff_hz"),  # above half the 100 Hz control rate
        ({"flush_interval_s": 0.0}, "flush_interval_s"),
        ({"control_dt": -0.01}, "control_dt"),
        ({"control_dt": math.nan}, "control_dt"),
        ({"omega_ref": math.inf}, "omega_ref"),
        ({"episode_duration": -1.0}, "episode_duration"),
        ({"observation": "bogus"}, "observation"),
        ({"limits": "tight"}, "limits"),
        ({"baudrate": 0}, "baudrate"),
    ]:
        with pytest.raises(InputError, match=what):
            HardwareEnv(DEVICE, **kw)  # refused before the port is opened (/dev/null is no serial port)
    with pytest.raises(InputError, match="not a rig configuration|configuration"):
        HardwareEnv(DEVICE, "bogus")
    with pytest.raises(InputError, match="serial device"):
        HardwareEnv(str(tmp_path))
    for bad in (0.0, -1.0, math.nan, math.inf, 2.0, "0.1"):
        with pytest.raises(InputError, match="reply_timeout"):
            RigClient(DEVICE, reply_timeout=bad)
    for kw in ({"latency_s": math.nan}, {"jitter_s": -1.0}, {"lvdt_noise_std": math.inf}, {"alpha0": math.nan}):
        with pytest.raises(InputError, match=next(iter(kw))):
            RigEmulator(**kw)
    for kw in ({"watchdog_s": 100.0}, {"watchdog_s": math.nan}, {"control_period_s": 1e6}, {"counts_per_rev": 0}):
        with pytest.raises(InputError):
            FirmwareConfig(**kw)


def test_numbers_are_shown_as_given():
    with pytest.raises(InputError) as exc:
        number(np.float64(-2.5), "--x", low=0.0)
    assert "got -2.5" in str(exc.value) and "np." not in str(exc.value)
    with pytest.raises(TypeError, match="must be a number"):
        number("2", "duration")


def _failing_recorder(tmp_path) -> EpisodeRecorder:
    rec = EpisodeRecorder(tmp_path / "rec.csv", False, {"source": "test"}, flush_interval_s=0.01)

    def full(row):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    rec._writer.write = full
    return rec


def test_disk_error_while_recording_is_one_line_saying_what_is_kept(tmp_path, eventually):
    rec = _failing_recorder(tmp_path)
    rec.write({"t": 0.0})  # the writer thread meets the error on its own time
    assert eventually(lambda: rec.failed)
    with pytest.raises(RecordingError) as exc:
        rec.write({"t": 0.01})
    msg = str(exc.value)
    assert isinstance(exc.value, SafetyError) and "\n" not in msg
    assert "No space left on device" in msg and f"kept in {tmp_path / 'rec.csv'}" in msg
    rec.write({"t": 0.02})  # said once: later rows are dropped quietly
    rec.close()  # and not said again
    assert (tmp_path / "rec.csv").read_text().startswith("# meta:")  # the header written before the error is kept


def test_disk_error_mid_episode_stops_the_motor_and_keeps_the_recording(tmp_path, eventually):
    with RigEmulator("torsional", dt=5e-3, firmware=FirmwareConfig(watchdog_s=2.0)) as emu:
        env = HardwareEnv(emu.port, record=tmp_path / "run.csv", reply_timeout=0.5, episode_duration=5.0)
        env.reset(seed=0)
        for _ in range(30):
            env.step(np.array([0.2]))
        env.recorder._writer.close()  # the file system goes away under the writer
        env.recorder._writer._fh = None
        with pytest.raises(RecordingError, match="kept in"):
            for _ in range(200):
                env.step(np.array([0.2]))
        assert eventually(lambda: emu.firmware.volts == 0.0)
        with pytest.raises(SafetyError, match="not running"):
            env.step(np.array([0.2]))
        env.close()
    assert (tmp_path / "run.csv").stat().st_size > 0


def test_linear_policy_file_checks(tmp_path):
    LinearPolicy(np.zeros((1, 7)), np.zeros(1)).save(tmp_path / "p.npz")
    assert isinstance(load_policy(tmp_path / "p.npz"), LinearPolicy)
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(InputError, match="empty.npz"):
        load_policy(tmp_path / "empty.npz")


def test_emulate_takes_a_partial_parameter_file_as_every_command_does(tmp_path):
    from drillgym import RigParams
    from drillgym.commands.plant import plant_from_cli

    f = tmp_path / "partial.json"
    f.write_text('{"Ju": 0.5}')
    base, comp, _ = plant_from_cli(f, None, None)  # what `rig emulate --params` builds its plant from
    assert base.Ju == 0.5 and base.km == RigParams().km and not comp.effects
    emu = RigEmulator("torsional", params=base, dt=5e-3)
    assert emu.firmware.params.Ju == 0.5
