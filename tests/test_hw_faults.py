"""Link and process faults: each detected with a clear error, the motor at 0 V within 100 ms
(the emulator's voltage log says when), the recording intact up to the fault."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import hw
from drillgym.io import read_timeseries
from hw import protocol as P
from hw.emulator import FaultPlan, RigEmulator
from hw.env import HardwareEnv
from hw.firmware import Firmware
from hw.link import LinkCorruptError, LinkLostError, LinkTimeoutError

FAULT_AT = 40  # SET_VOLTAGE index of the fault (the rest phase sends 21 zero commands first)
ZERO_WITHIN = 0.100  # s
VENV_BIN = Path(sys.executable).parent


@pytest.fixture(autouse=True)
def _fast_thread_switching():
    """Host and emulator share one interpreter here (a real rig runs on its own microcontroller):
    switch threads every 0.5 ms instead of 5 ms so the emulated watchdog is not held up by the host."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(5e-4)
    yield
    sys.setswitchinterval(old)


class _HostStarved(Exception):
    """The firmware's watchdog stopped the motor, or a reply was late, before the planned fault: the test
    process (host and emulator in one interpreter, on a loaded machine) was starved longer than the
    watchdog period or the reply timeout."""


def _run_until_fault(env, on_step=None, max_steps=200):
    try:
        env.reset(seed=0)  # 21 zero commands: the planned faults come later (FAULT_AT)
    except hw.link.LinkError as exc:
        raise _HostStarved(f"link error in the rest phase, before the planned fault: {exc}") from exc
    steps = 0
    with pytest.raises(hw.link.LinkError) as err:
        while steps < max_steps:
            _, _, terminated, _, info = env.step(np.array([3.0], dtype=np.float32))
            if terminated and info.get("safety_stop") == "WATCHDOG":
                raise _HostStarved(f"watchdog stop at step {steps + 1}, before the planned fault")
            steps += 1
            if on_step is not None:
                on_step(steps)
    return err.value, steps


def _check_recording(path, steps):
    rec = read_timeseries(path)
    assert len(rec) == steps + 1  # every sample before the fault, nothing after
    np.testing.assert_allclose(rec.t, np.arange(steps + 1) * 0.01, atol=1e-9)
    assert np.all(rec.u[:-1] == 3.0) and rec.u[-1] == 0.0  # a row's u applies from its time on


@pytest.mark.parametrize(
    "fault, error, message",
    [
        (FaultPlan(corrupt_sample=FAULT_AT), LinkCorruptError, "CRC mismatches so far: 1"),
        (FaultPlan(drop_sample=FAULT_AT), LinkTimeoutError, "no SAMPLE reply to SET_VOLTAGE"),
        (FaultPlan(drop_command=FAULT_AT), LinkTimeoutError, "no SAMPLE reply to SET_VOLTAGE"),
        (FaultPlan(delay_command=FAULT_AT, delay_s=0.3), LinkTimeoutError, "frame lost or late"),
    ],
    ids=["corrupted-bytes", "dropped-sample", "dropped-command", "late-frame"],
)
def test_link_fault_detected_motor_stopped_recording_intact(tmp_path, fault, error, message):
    for attempt in range(3):  # a fresh rig when a starved test process let the watchdog stop it first
        rec = tmp_path / f"rec{attempt}.csv"
        with RigEmulator("torsional", dt=5e-3, faults=fault) as emu:
            env = HardwareEnv(emu.port, record=rec, episode_duration=5.0)
            try:
                exc, steps = _run_until_fault(env)
            except _HostStarved:
                env.close()
                continue
            if not emu.fault_times:  # a link error before the planned fault: a late reply, the host starved
                env.close()
                continue
            assert isinstance(exc, error) and message in str(exc) and "recording kept up to the fault" in str(exc)
            ((kind, t_fault),) = emu.fault_times.items()
            time.sleep(0.15)
            delay = emu.zero_delay(t_fault)
            assert delay is not None and delay <= ZERO_WITHIN, f"motor at 0 V {delay} s after {kind}"
            with pytest.raises(hw.env.SafetyError, match="after a fault"):
                env.step(np.array([1.0]))
            if kind == "delay_command":  # the late command was executed; the watchdog had stopped the motor first
                assert emu.firmware.events[-1].cause in ("watchdog", "host")
            env.close()
        _check_recording(rec, steps)
        assert steps == FAULT_AT - 22
        return
    pytest.fail("the watchdog stopped the rig before the planned fault in 3 attempts (test process starved)")


@pytest.mark.parametrize("fault", ["kill", "unplug"])
def test_emulator_killed_or_port_unplugged(tmp_path, fault):
    for attempt in range(3):  # a fresh rig when a starved test process faulted the link before the planned fault
        rec = tmp_path / f"rec{attempt}.csv"
        with RigEmulator("torsional", dt=5e-3) as emu:
            env = HardwareEnv(emu.port, record=rec, episode_duration=5.0)
            t_fault = []

            def inject(step, emu=emu, t_fault=t_fault):
                if step == 30:
                    time.sleep(0.005)  # the fault strikes mid-period
                    t_fault.append(getattr(emu, fault)())

            try:
                exc, steps = _run_until_fault(env, inject)
            except _HostStarved:
                env.close()
                continue
            if not t_fault:  # a link error (late reply) before step 30: the host was starved, not the fault
                env.close()
                continue
            expected = LinkTimeoutError if fault == "kill" else LinkLostError
            assert isinstance(exc, expected), exc
            assert ("firmware not responding" if fault == "kill" else "disconnected") in str(exc)
            time.sleep(0.15)
            delay = emu.zero_delay(t_fault[0])
            assert delay is not None and delay <= ZERO_WITHIN  # the firmware's watchdog
            # killed: the firmware's watchdog; unplugged: the firmware sees the detach
            assert emu.firmware.stop_reason == (P.StopReason.WATCHDOG if fault == "kill" else P.StopReason.LINK_LOST)
            env.close()
        _check_recording(rec, 30)
        return
    pytest.fail("the link faulted before the planned fault in 3 attempts (test process starved)")


def test_emulator_process_killed(tmp_path):
    """`drillgym rig emulate` SIGKILLed mid-episode: the host sees the port vanish."""
    link = tmp_path / "rig"
    proc = subprocess.Popen(
        [str(VENV_BIN / "drillgym"), "rig", "emulate", "--port", str(link), "--dt", "0.005"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert "rig emulator (torsional) on /dev/pts/" in line and link.is_symlink()
        # the killed emulator's pty closes once the kernel has torn the process down (its memory before its files),
        # which on a loaded machine took longer than a 50 ms reply timeout: wait long enough to see the port vanish
        env = HardwareEnv(str(link), record=tmp_path / "rec.csv", episode_duration=5.0, reply_timeout=0.5)
        exc, steps = _run_until_fault(env, lambda k: k == 25 and os.kill(proc.pid, signal.SIGKILL))
        assert isinstance(exc, LinkLostError) and "disconnected" in str(exc)
        env.close()
    finally:
        proc.kill()
        proc.wait()
    _check_recording(tmp_path / "rec.csv", steps)
    assert steps in (25, 26)


def _kill_host_mid_run(tmp_path, attempt):
    """Start `drillgym rig run` on an emulator, SIGKILL it once >= 60 episode steps ran.
    Returns (emulator, commands at the kill, kill time, recording path), or None when the host
    stopped by itself first (a CPU-starved host trips the 100 ms watchdog: legitimate, but not
    the scenario under test)."""
    rec = tmp_path / f"run{attempt}.csv"
    emu = RigEmulator("torsional", dt=5e-3)
    emu.__enter__()
    proc = subprocess.Popen(
        [
            str(VENV_BIN / "drillgym"),
            "rig",
            "run",
            "--port",
            emu.port,
            "--controller",
            "const:2.5",
            "--duration",
            "20",
            "--record",
            str(rec),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        t_end = time.monotonic() + 180
        while emu.firmware.commands < 21 + 60 and proc.poll() is None and time.monotonic() < t_end:
            time.sleep(0.01)
        if proc.poll() is not None:
            emu.__exit__(None, None, None)
            return None
        proc.send_signal(signal.SIGKILL)
        t_kill = time.monotonic()
        proc.wait()
    finally:
        proc.kill()
    return emu, emu.firmware.commands, t_kill, rec


def test_host_killed_watchdog_stops_motor_recording_loses_at_most_1s(tmp_path):
    """`drillgym rig run` SIGKILLed: the firmware watchdog stops the motor, the recording keeps all
    but the last flush interval (<= 0.5 s)."""
    for attempt in range(3):
        run = _kill_host_mid_run(tmp_path, attempt)
        if run is not None:
            break
    assert run is not None, "the host never ran 60 steps without being starved (3 attempts)"
    emu, n_cmd, t_kill, rec_path = run
    try:
        time.sleep(0.2)
        assert emu.firmware.stop_reason == P.StopReason.WATCHDOG
        # the watchdog runs from the last command *received*: one in flight at the kill arrives after it
        # (seen in CI: 0.13 ms after, motor at 0 V 100.13 ms after the kill), nothing later
        last = emu.firmware.last_command
        assert last is not None and last <= t_kill + 0.05
        assert emu.zero_delay(max(t_kill, last)) <= ZERO_WITHIN + 1e-9
    finally:
        emu.__exit__(None, None, None)
    rec = read_timeseries(rec_path)
    episode_steps = n_cmd - 21
    assert episode_steps >= 60 and episode_steps - 100 <= len(rec) - 1 <= episode_steps


def test_firmware_watchdog_and_limits_without_threads():
    fw = Firmware("torsional", dt=5e-3)
    (reply,) = fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, 0, P.SetVoltage(12.0).pack()), now=0.0)
    sample = P.decode(P.FrameParser().feed(reply)[0])
    assert sample.volts == 5.0 and sample.status & P.Status.LIMITED  # clamped to the amplifier range
    assert fw.poll(0.099) == [] and fw.volts == 5.0
    (stop,) = fw.poll(0.130)  # a late poll (starved emulator thread): the hardware timer fired at 0.100
    assert fw.events[-1].time == pytest.approx(0.100) and fw.events[-1].volts == 0.0
    assert P.decode(P.FrameParser().feed(stop)[0]) == P.EmergencyStop(P.StopReason.WATCHDOG) and fw.volts == 0.0
    frames = fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, 1, P.SetVoltage(2.0).pack()), now=0.2)
    s = P.decode(P.FrameParser().feed(frames[0])[0])
    assert s.volts == 0.0 and s.status & P.Status.STOPPED and s.status & P.Status.WATCHDOG  # latched
    fw.handle(P.Frame(P.MsgType.CLEAR_STOP, 2, b""), now=0.3)
    frames = fw.handle(P.Frame(P.MsgType.SET_VOLTAGE, 4, P.SetVoltage(2.0).pack()), now=0.31)
    s = P.decode(P.FrameParser().feed(frames[0])[0])
    assert s.volts == 2.0 and s.status == P.Status.SEQ_GAP and fw.seq_gaps == 1  # seq 3 missing
