"""drillgym/Hardware-v0 against the emulator over a real pseudo-terminal: episodes match simulation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import drillgym.envs  # noqa: F401 - registers the simulated envs
import hw
import hw.env  # noqa: F401 - hw.env.HardwareEnv below (not imported by the package itself)
from drillgym.io import read_timeseries
from drillgym.measurement import counts_to_angle
from drillgym.params import RigParams
from hw import protocol as P
from hw.emulator import RigEmulator
from hw.firmware import FirmwareConfig
from hw.runner import LinearPolicy, load_policy, measurement_of, run_episode
from hw.safety import SafetyLimits

hw.register()
# These tests check behaviour, not timing (tests/test_hw_faults.py does): a relaxed watchdog and the longest
# reply timeout the client accepts keep them deterministic on a loaded machine (a CI run with two pytest
# workers on two cores once waited over 500 ms for a reply).
RELAXED = FirmwareConfig(watchdog_s=2.0)
REPLY = 1.0
CPR = 8000
COUNT = counts_to_angle(1, CPR)  # encoder resolution (rad)


class SpeedP:
    """A tiny proportional speed controller (controllers/ interface: reset(m), __call__(m) -> V)."""

    def reset(self, m):
        self.prev, self.ref = (m["t"], m["theta_l"]), m["omega_ref"]

    def __call__(self, m):
        dt = max(m["t"] - self.prev[0], 1e-3)
        w = (m["theta_l"] - self.prev[1]) / dt if m["t"] > self.prev[0] else 0.0
        self.prev = (m["t"], m["theta_l"])
        return float(np.clip(2.0 + 0.4 * (self.ref - w), -5, 5))


def _sim_env(seed, **opts):
    env = gym.make("drillgym/Torsional-v0", lvdt_noise_std=0.0, normalize_action=False, **opts)  # volts, as the rig
    obs, info = env.reset(seed=seed)
    return env, obs, info, float(env.unwrapped.batch.system.alpha[0])


def _sim_measurement(env, obs, t):
    s = env.unwrapped.batch.system
    from drillgym.measurement import quantize_angle

    return {
        "t": t,
        "theta_u": float(quantize_angle(s.theta_u[0], CPR)),
        "theta_l": float(quantize_angle(s.theta_l[0], CPR)),
        "x": 0.0,
        "y": 0.0,
        "omega_ref": float(env.unwrapped.batch.omega_ref[0]),
    }


def test_controller_episode_matches_simulation(tmp_path, eventually):
    opts = dict(observation="sensors", episode_duration=1.5)
    sim, obs_s, _, alpha0 = _sim_env(11, **opts)
    with RigEmulator("torsional", firmware=RELAXED, dt=sim.unwrapped.options.dt, alpha0=alpha0) as emu:
        env = gym.make(hw.ENV_ID, port=emu.port, record=tmp_path / "ctrl.csv", reply_timeout=REPLY, **opts)
        ctrl_h, ctrl_s = SpeedP(), SpeedP()
        res = run_episode(env, controller=ctrl_h, seed=11)
        env.close()
        assert eventually(lambda: emu.firmware.volts == 0.0)  # close() leaves the motor at 0 V
    assert res.truncated and res.steps == 150 and res.safety_stop is None
    # the same episode in simulation
    ctrl_s.reset(_sim_measurement(sim, obs_s, 0.0))
    theta, us = [], []
    for k in range(150):
        u = ctrl_s(_sim_measurement(sim, obs_s, k * 0.01))
        obs_s, *_ = sim.step(np.array([u], dtype=np.float32))
        s = sim.unwrapped.batch.system
        theta.append((s.theta_u[0], s.theta_l[0]))
        us.append(u)
    rec = read_timeseries(tmp_path / "ctrl.csv")
    assert rec.meta["source"] == "emulator" and rec.configuration.label == "torsional"
    np.testing.assert_allclose(rec.t, np.arange(151) * 0.01, atol=1e-9)
    # docs/data_format.md: a row's u is applied from its time on (zero-order hold): the command of step k on the
    # row of t_k, and 0 V on the last row (the episode ended); the simulator reads the file the same way
    np.testing.assert_allclose(rec.u[:-1], us, atol=1e-12)
    assert rec.u[-1] == 0.0
    theta = np.array(theta)
    assert np.max(np.abs(rec.theta_u[1:] - theta[:, 0])) <= COUNT  # to encoder resolution
    assert np.max(np.abs(rec.theta_l[1:] - theta[:, 1])) <= COUNT
    assert rec.theta_u[-1] - rec.theta_u[0] > 100 * COUNT  # it did turn


def test_policy_episode_matches_simulation(tmp_path):
    opts = dict(observation="motor", motor_history=4, episode_duration=1.0, omega_ref=3.0)
    sim, obs_s, _, alpha0 = _sim_env(5, **opts)
    W = np.zeros((1, obs_s.size))
    W[0, 0], W[0, 4], W[0, -1] = -0.3, 0.2, 0.5  # u = 1.5 - 0.3 w_inc0 + 0.2 u_prev + ...
    LinearPolicy(W, np.array([1.5])).save(tmp_path / "policy.npz")
    policy = load_policy(tmp_path / "policy.npz")
    with RigEmulator("torsional", firmware=RELAXED, dt=sim.unwrapped.options.dt, alpha0=alpha0) as emu:
        env = gym.make(hw.ENV_ID, port=emu.port, record=tmp_path / "pol.csv", reply_timeout=REPLY, **opts)
        assert env.observation_space == sim.observation_space and env.action_space == sim.action_space
        obs_h, _ = env.reset(seed=5)
        np.testing.assert_array_equal(obs_h, obs_s)
        for _ in range(100):
            obs_h, r_h, term, trunc, info = env.step(policy(obs_h))
            obs_s, *_ = sim.step(policy(obs_s))
            np.testing.assert_allclose(obs_h, obs_s, atol=COUNT / 0.01 + 1e-5)  # one count per period
        assert trunc and not term and info["overruns"] <= 5
        env.close()
    rec = read_timeseries(tmp_path / "pol.csv")
    assert len(rec) == 101 and abs(rec.theta_u[-1] - sim.unwrapped.batch.system.theta_u[0]) <= COUNT


def test_reset_brings_spinning_rig_to_rest_and_lvdt_offset_removed(tmp_path):
    hidden = dict(effects=["lvdt_offset"], effect_params={"lvdt_x0": 1e-3, "lvdt_y0": -5e-4})  # LVDT offsets at rest
    with RigEmulator("coupled", firmware=RELAXED, dt=5e-3, **hidden) as emu:
        env = gym.make(
            hw.ENV_ID,
            port=emu.port,
            configuration="coupled",
            record=tmp_path / "run.csv",
            episode_duration=0.5,
            omega_ref=4.0,
            reply_timeout=REPLY,
        )
        run_episode(env, controller=measurement_const(4.0), seed=1)
        assert abs(emu.firmware.sim.omega_u[0]) > 1.0  # still turning after the episode (0 V, coasting)
        obs, info = env.reset(seed=2)
        assert emu.firmware.sim.stuck_l[0] and emu.firmware.sim.stuck_u[0]  # at rest
        m = info["measurement"]
        assert abs(m["x"]) < 1e-6 and abs(m["y"]) < 1e-6  # offsets taken at rest
        assert abs(m["lvdt_x_raw"] * 1e-7 - (1e-3 + emu.firmware.sim.lateral_fixed[0][0])) < 1e-6
        for _ in range(20):
            obs, *_ = env.step(np.array([2.0], dtype=np.float32))
        env.close()
    first = read_timeseries(tmp_path / "run.csv")
    second = read_timeseries(tmp_path / "run_001.csv")
    assert {"x", "y", "x_lp", "counts_l"} <= set(first.columns) and len(first) == 51 and len(second) == 21
    assert second.configuration.label == "coupled" and np.all(np.abs(second.x) < 1e-3)


def measurement_const(v):
    from hw.runner import ConstantController

    return ConstantController(v)


def test_host_safety_layer_clamps_slews_and_stops(tmp_path, eventually):
    limits = SafetyLimits(v_max=4.0, slew_v_per_s=100.0, max_speed=2.0)
    with RigEmulator("torsional", firmware=RELAXED, dt=5e-3) as emu:
        env = gym.make(
            hw.ENV_ID,
            port=emu.port,
            record=tmp_path / "s.csv",
            limits=limits,
            episode_duration=5.0,
            reply_timeout=REPLY,
        )
        env.reset(seed=0)
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array([np.nan]))
        stop, k = None, 0
        while stop is None and k < 300:
            *_, term, trunc, info = env.step(np.array([50.0]))  # far out of range
            stop, k = info.get("safety_stop"), k + 1
        assert term and stop == "OVERSPEED" and info["termination"].startswith("safety stop: OVERSPEED at t = ")
        assert eventually(lambda: emu.firmware.volts == 0.0 and emu.firmware.stop_reason == P.StopReason.HOST)
        with pytest.raises(hw.env.SafetyError, match="not running"):
            env.step(np.array([1.0]))
        env.close()
    rec = read_timeseries(tmp_path / "s.csv")
    du = np.diff(rec.columns["u_cmd"])
    assert rec.columns["u_cmd"].max() == 4.0 and np.all(du <= 100.0 * 0.01 + 1e-12)  # clamp and slew


def test_measurement_helper_and_bad_options(tmp_path):
    with RigEmulator("torsional", dt=5e-3, firmware=RELAXED) as emu:
        with pytest.raises(ValueError, match="do not apply to the hardware"):
            hw.env.HardwareEnv(emu.port, params=RigParams())
        with pytest.raises(ValueError, match="effects"):  # hidden effects belong to the rig, not the host
            hw.env.HardwareEnv(emu.port, effects=["input_delay"])
        with pytest.raises(ValueError, match="refused"):
            hw.env.HardwareEnv(emu.port, control_dt=0.0123)
        with pytest.raises(FileNotFoundError, match="does not exist"):
            hw.env.HardwareEnv(str(tmp_path / "no-such-port"))
        env = hw.env.HardwareEnv(emu.port, record=tmp_path, reply_timeout=REPLY)  # a 50 ms timeout failed in CI
        _, info = env.reset(seed=0)
        m = measurement_of(info)
        assert set(m) == {"t", "theta_u", "theta_l", "x", "y", "omega_ref"} and m["t"] == 0.0
        env.close()
        env.close()  # twice is fine
    assert len(list(tmp_path.glob("*_ep0000.csv"))) == 1


def test_an_episode_ends_with_a_stop_the_firmware_acknowledged_or_says_it_was_not(tmp_path):
    """end_episode waits for the ACK of its EMERGENCY_STOP (retrying): when it returns acknowledged the
    firmware is at 0 V; a dead firmware is reported (the watchdog is then the motor's only stop)."""
    with RigEmulator("torsional", dt=5e-3, firmware=RELAXED) as emu:
        env = hw.env.HardwareEnv(emu.port, record=tmp_path, reply_timeout=REPLY)
        env.reset(seed=0)
        env.step(np.array([0.5], dtype=np.float32))
        env.end_episode()
        assert env.stop_acknowledged is True
        assert emu.firmware.stop_reason == P.StopReason.HOST and emu.firmware.volts == 0.0  # no waiting needed
        env.reset(seed=1)
        env.step(np.array([0.5], dtype=np.float32))
        emu.kill()
        env.end_episode()
        assert env.stop_acknowledged is False
        env.close()
