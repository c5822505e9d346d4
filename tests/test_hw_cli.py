"""`drillgym rig` from an operator's seat, through subprocesses against the emulator: safety stops and
Ctrl-C exit non-zero with one line (motor at 0 V, recording kept), e-stop, dry run, reconnect, the clamp
notice, the emulator's log, and a run on a loaded machine with the default 100 ms watchdog."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from drillgym.io import read_timeseries
from hw import protocol as P
from hw.emulator import RigEmulator
from hw.firmware import Firmware
from hw.runner import LinearPolicy

# The rig commands run at real-time priority (SCHED_FIFO): one worker runs all of them, so no two
# real-time emulators and hosts compete for the two cores (the loaded-machine test brings its own load).
pytestmark = pytest.mark.xdist_group("rig-realtime")

REST_COMMANDS = 21  # zero-volt commands of the rest phase before the episode's first step
ENV = {
    **os.environ,
    "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")]),
}


def cli(*args, **kw):
    return subprocess.Popen(
        [sys.executable, "-m", "drillgym.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=ENV,
        **kw,
    )


def run(*args, timeout=180):
    p = cli(*args)
    out, err = p.communicate(timeout=timeout)
    return p.returncode, out, err


def wait_commands(emu, n, proc, timeout=120.0):
    t_end = time.monotonic() + timeout
    while emu.firmware.commands < n and proc.poll() is None and time.monotonic() < t_end:
        time.sleep(0.005)
    assert proc.poll() is None, proc.communicate()
    assert emu.firmware.commands >= n, "the host never got going"


@pytest.fixture
def emu():
    log: list[str] = []
    with RigEmulator("torsional", dt=5e-3, log=log.append) as e:
        e.log = log
        yield e


def test_watchdog_stop_exits_3_with_one_line(tmp_path, emu):
    rec = tmp_path / "run.csv"
    p = cli("rig", "run", "--port", emu.port, "--controller", "const:1.0", "--duration", "20", "--record", str(rec))
    wait_commands(emu, REST_COMMANDS + 20, p)
    p.send_signal(signal.SIGSTOP)  # the host stalls (a loaded machine at its worst): the watchdog must stop the motor
    time.sleep(0.4)
    p.send_signal(signal.SIGCONT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 3, (out, err)
    assert err.count("\n") == 1 and err.startswith("drillgym: safety stop after ") and "WATCHDOG" in err, err
    assert f"motor at 0 V, recording kept: {rec}" in err
    assert emu.firmware.stop_reason == P.StopReason.WATCHDOG and emu.firmware.volts == 0.0
    assert any("WATCHDOG (no command for" in m for m in emu.log), emu.log
    ts = read_timeseries(rec)
    assert len(ts) >= 21 and np.all(ts.u[0:20] == 1.0)  # a row's u applies from its time on


def test_ctrl_c_exits_130_with_one_line(tmp_path, emu, eventually):
    """Also when the process inherited an ignored SIGINT (a parent's SIG_IGN passes on to its children)."""
    rec = tmp_path / "run.csv"
    p = cli(
        "rig",
        "run",
        "--port",
        emu.port,
        "--controller",
        "const:1.0",
        "--duration",
        "60",
        "--record",
        str(rec),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    wait_commands(emu, REST_COMMANDS + 20, p)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130, (out, err)
    assert err == f"drillgym: interrupted: motor stopped (0 V), recording kept: {rec}\n", err
    assert eventually(lambda: emu.firmware.stop_reason == P.StopReason.HOST and emu.firmware.volts == 0.0)
    assert len(read_timeseries(rec)) >= 15  # the steps before the interrupt (the count above races the host by one)


def test_firmware_over_speed_stop_exits_3(tmp_path):
    from hw.firmware import FirmwareConfig
    from hw.safety import SafetyLimits

    fw = FirmwareConfig(limits=SafetyLimits(max_speed=0.5))
    with RigEmulator("torsional", firmware=fw, dt=5e-3) as e:
        code, out, err = run(
            "rig",
            "run",
            "--port",
            e.port,
            "--controller",
            "const:5",
            "--duration",
            "10",
            "--record",
            str(tmp_path / "r.csv"),
        )
        assert e.firmware.stop_reason == P.StopReason.OVERSPEED and e.firmware.volts == 0.0
    assert code == 3 and err.count("\n") == 1 and "OVERSPEED: over-speed" in err, (out, err)


def test_estop_from_the_command_line(tmp_path, emu, eventually):
    code, out, err = run("rig", "estop", "--port", emu.port)
    assert code == 0 and "emergency stop acknowledged" in out, (out, err)
    assert emu.firmware.stop_reason == P.StopReason.HOST and emu.firmware.volts == 0.0
    # while a run is going: that run stops (exit 3), the motor is at 0 V
    rec = tmp_path / "run.csv"
    p = cli("rig", "run", "--port", emu.port, "--controller", "const:1.0", "--duration", "20", "--record", str(rec))
    wait_commands(emu, REST_COMMANDS + 20, p)
    assert emu.firmware.volts == 1.0  # the run's handshake cleared the latched stop
    code, out, err = run("rig", "estop", "--port", emu.port)
    assert code in (0, 3), (out, err)  # the ACK may be read by the running host instead
    out, err = p.communicate(timeout=60)
    assert p.returncode == 3 and err.startswith("drillgym: safety stop"), (out, err)
    # two programs on one port steal each other's bytes: the running host may see a broken frame first and stop
    # on it; the e-stop, the host's own stop or (both lost) the watchdog leaves the motor at 0 V
    assert eventually(
        lambda: emu.firmware.volts == 0.0 and emu.firmware.stop_reason in (P.StopReason.HOST, P.StopReason.WATCHDOG)
    )
    code, out, err = run("rig", "estop", "--port", str(tmp_path / "nothing"))
    assert code == 2 and "does not exist" in err


def test_estop_without_acknowledgement_exits_3(tmp_path, emu):
    emu.kill()  # the firmware's main loop is dead: no ACK comes
    code, out, err = run("rig", "estop", "--port", emu.port, "--attempts", "2", "--timeout-ms", "50")
    assert code == 3 and "sent 2 times, no acknowledgement" in err and err.count("\n") == 1, (out, err)


def test_dry_run_sends_no_voltage(tmp_path, emu):
    code, out, err = run(
        "rig",
        "run",
        "--port",
        emu.port,
        "--controller",
        "const:20",
        "--record",
        str(tmp_path / "new" / "r.csv"),
        "--dry-run",
    )
    assert code == 0, (out, err)
    assert "control period 10 ms accepted, watchdog 100 ms" in out and "20 V will be clamped to +-5 V" in out
    assert "nothing was sent that moves the motor" in out
    assert emu.firmware.commands == 0 and not (tmp_path / "new").exists()
    assert not any(m.startswith("motor stopped") and "HOST" not in m for m in emu.log)
    LinearPolicy(np.zeros((1, 3)), np.zeros(1)).save(tmp_path / "bad.npz")  # the sensors observation has 7 values
    code, out, err = run("rig", "run", "--port", emu.port, "--policy", str(tmp_path / "bad.npz"), "--dry-run")
    assert code == 2 and "linear policy expects an observation of 3 values" in err, (out, err)
    code, out, err = run("rig", "run", "--port", emu.port, "--controller", "nonsense:1", "--dry-run")
    assert code == 2 and err.count("\n") == 1, (out, err)
    assert emu.firmware.commands == 0


def test_clamp_is_told_once_and_kept(tmp_path, emu):
    for attempt in range(3):  # a fresh rig when the emulator's thread was starved past the reply timeout
        rec = tmp_path / f"missing{attempt}" / "dir" / "r.csv"  # --record creates missing directories
        rig = emu if attempt == 0 else RigEmulator("torsional", dt=5e-3)
        if rig is not emu:
            rig.start()
        try:
            code, out, err = run(
                "rig", "run", "--port", rig.port, "--controller", "const:20", "--duration", "0.5", "--record", str(rec)
            )
        finally:
            if rig is not emu:
                rig.stop()
        # a link fault or a watchdog stop (no reply, or no command seen, within 100 ms: seen in full `make test`
        # runs with the other worker and other jobs busy) is this process's emulator thread being starved at
        # normal priority, not the clamp: the safety stops themselves are tested above
        if not (code == 3 and ("motor stop requested" in err or "WATCHDOG" in out)):
            break
    assert code == 0, (out, err)
    assert err.count("note:") == 1 and "20 V asked for at step 1; the amplifier gives +-5 V" in err, err
    assert "50 of 50 commands were clamped to the amplifier range" in out
    u = read_timeseries(rec).u  # a row's u applies from its time on; 0 V after the episode
    assert np.all(u[:-1] == 5.0) and u[-1] == 0.0


def test_reconnect_after_the_port_went_away(tmp_path):
    link = tmp_path / "rig"
    rec = tmp_path / "run.csv"
    first = RigEmulator("torsional", dt=5e-3, link_path=link)
    first.start()
    p = cli(
        "rig",
        "run",
        "--port",
        str(link),
        "--controller",
        "const:1.0",
        "--duration",
        "1.0",
        "--record",
        str(rec),
        "--reconnect",
        "1",
        "--reconnect-wait",
        "0.5",
    )
    try:
        wait_commands(first, REST_COMMANDS + 20, p)
    finally:
        first.stop()  # the port disappears (unplugged)
    with RigEmulator("torsional", dt=5e-3, link_path=link) as second:  # and comes back
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, (out, err)
        assert second.firmware.commands >= REST_COMMANDS + 100
    assert "link fault" in err and "reconnecting in 0.5 s (1 of 1)" in err
    # the first episode's recording, up to the fault: the rest row and the replies of steps 1..19 at least
    # (step 20's command reached the firmware, so step 19's reply reached the host; step 20's reply may not)
    assert len(read_timeseries(rec)) >= 20
    assert len(read_timeseries(tmp_path / "run_001.csv")) == 101  # the new episode, complete


def test_emulate_logs_connections_and_stops(tmp_path):
    link = tmp_path / "rig"
    emu = cli("rig", "emulate", "--port", str(link), "--dt", "0.005")
    try:
        assert "rig emulator (torsional) on /dev/pts/" in emu.stdout.readline()
        code, out, err = run(
            "rig",
            "run",
            "--port",
            str(link),
            "--controller",
            "const:1",
            "--duration",
            "0.3",
            "--record",
            str(tmp_path / "r.csv"),
        )
        assert code == 0, (out, err)
        assert run("rig", "estop", "--port", str(link))[0] == 0
    finally:
        emu.send_signal(signal.SIGTERM)
        out, err = emu.communicate(timeout=30)
    assert "host connected: IDENTIFY (control period 10 ms)" in err
    assert "motor stopped (0 V, latched): HOST" in err  # the end of the episode
    assert "emergency stop from the host (already stopped: HOST)" in err
    assert "emulator stopped" in err


def test_watchdog_counts_commands_waiting_in_the_receive_buffer():
    fw = Firmware("torsional", dt=5e-3)
    fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, 0, P.SetVoltage(2.0).pack()), now=0.0)
    assert fw.poll(0.15, rx_pending=True) == [] and fw.volts == 2.0  # a command has arrived, not parsed yet
    assert fw.poll(0.15) != [] and fw.stop_reason == P.StopReason.WATCHDOG  # nothing was waiting: stop
    fw = Firmware("torsional", dt=5e-3)
    fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, 0, P.SetVoltage(2.0).pack()), now=0.0)
    assert fw.poll(0.2, rx_pending=True) != [] and fw.volts == 0.0  # never beyond two watchdog periods


@pytest.mark.slow
def test_default_watchdog_run_completes_on_a_loaded_machine(tmp_path):
    """Two busy processes load both cores while `rig emulate` and `rig run` (300 steps at 10 ms) share them
    with the default 100 ms watchdog and reply timeout: the run completes.  One retry: a sandbox that
    accepts but does not honour real-time scheduling (seen once in CI) can starve a run; two failures in
    a row fail the test with both messages."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    failures = []
    try:
        for attempt in range(2):
            link = tmp_path / f"rig{attempt}"
            record = tmp_path / f"r{attempt}.csv"
            emu = cli("rig", "emulate", "--port", str(link), "--dt", "0.005")
            try:
                assert "rig emulator" in emu.stdout.readline()
                code, out, err = run(
                    "rig",
                    "run",
                    "--port",
                    str(link),
                    "--controller",
                    "const:2.5",
                    "--duration",
                    "3",
                    "--record",
                    str(record),
                    timeout=300,
                )
            finally:
                emu.send_signal(signal.SIGTERM)
                emu.communicate(timeout=30)
            if code == 0:
                assert "300 steps" in out and len(read_timeseries(record)) == 301
                return
            # a clean stop, the file kept (or none yet: a fault while the rig was brought to rest, before the episode)
            # the message as a string: pytest prints it whole (a tuple is cut to 240 characters, the traceback lost)
            assert code == 3 and "safety stop" in err and (record.exists() or "nothing recorded yet" in err), (
                f"exit {code}; stderr:\n{err}"
            )
            failures.append(f"attempt {attempt + 1}: exit {code}; stdout: {out.strip()}; stderr: {err.strip()}")
        pytest.fail("\n".join(failures))
    finally:
        for h in hogs:
            h.kill()


def test_slow_disk_does_not_hold_up_the_control_loop(tmp_path, monkeypatch):
    """A 0.3 s fsync (a busy disk) during an episode at the default 100 ms watchdog: the episode completes,
    the recording is complete (the disk work runs beside the loop)."""
    from hw.env import HardwareEnv

    real_fsync = os.fsync

    def slow_fsync(fd):
        time.sleep(0.3)
        real_fsync(fd)

    with RigEmulator("torsional", dt=5e-3) as e:
        env = HardwareEnv(e.port, record=tmp_path / "r.csv", episode_duration=1.2, reply_timeout=None)
        env.reset(seed=0)
        monkeypatch.setattr(os, "fsync", slow_fsync)
        trunc = False
        while not trunc:
            _, _, term, trunc, info = env.step(np.array([2.0], dtype=np.float32))
            assert not term, info.get("safety_stop")
        env.close()
        assert e.firmware.stop_reason == P.StopReason.HOST  # the end of the episode, not the watchdog
    assert len(read_timeseries(tmp_path / "r.csv")) == 121


def test_run_restores_the_callers_signal_handlers():
    """``rig run`` called in-process (a notebook, CliRunner) must not leave Ctrl-C ignored afterwards."""
    from hw.commands.rig import _interruptible

    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with pytest.raises(KeyboardInterrupt):
            with _interruptible():
                assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # as the interrupt path does during the stop
                raise KeyboardInterrupt
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN  # the caller's own setting, restored
        assert signal.getsignal(signal.SIGTERM) == before[signal.SIGTERM]
    finally:
        for sig, h in before.items():
            signal.signal(sig, h)


def test_emulate_never_replaces_a_users_file_with_its_link(tmp_path):
    """`rig emulate --port data.csv` on an existing file: refused in one line, the file untouched."""
    data = tmp_path / "data.csv"
    data.write_text("t,u\n0,1\n")
    code, out, err = run("rig", "emulate", "--port", str(data), timeout=120)
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and "--port" in err and "exists (a file)" in err
    assert data.read_text() == "t,u\n0,1\n" and not data.is_symlink()


def test_emulator_link_replaces_only_a_stale_pty_link_and_removes_only_its_own(tmp_path):
    from drillgym.errors import OutputPathError

    other = tmp_path / "other"
    other.write_text("keep")
    elsewhere = tmp_path / "to_other"
    elsewhere.symlink_to(other)
    with pytest.raises(OutputPathError, match="not to a pseudo-terminal"):
        RigEmulator(link_path=elsewhere).start()
    assert elsewhere.is_symlink() and other.read_text() == "keep"

    stale = tmp_path / "sub" / "rig"  # under a missing folder, created
    stale.parent.mkdir()
    stale.symlink_to("/dev/pts/99999")  # left by an emulator that was killed
    emu = RigEmulator(link_path=stale)
    emu.start()
    try:
        assert os.readlink(stale) == emu.port
    finally:
        emu.stop()
    assert not stale.exists() and not stale.is_symlink()

    fresh = tmp_path / "missing" / "dir" / "rig"
    emu = RigEmulator(link_path=fresh)
    emu.start()
    try:
        assert os.readlink(fresh) == emu.port
    finally:
        emu.stop()
