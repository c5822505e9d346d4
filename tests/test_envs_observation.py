"""The 'sensors' and 'motor' observations against values computed independently from the true state.

Expected observations are rebuilt here from the env's true states with the public measurement
functions (``quantize_angle``, ``lvdt_measure``), the speed filter written out, and the sensor noise
stream re-drawn from a generator seeded as the env seeds its own (same draws, same order).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import drillgym  # noqa: F401  (registers the ids)
from drillgym.envs import EnvOptions, make_vec
from drillgym.envs.observation import MotorObservation, SensorObservation, fixed_frame_lateral
from drillgym.envs.task import SpeedTrackingTask
from drillgym.measurement import (
    EncoderVelocityEstimator,
    angle_to_counts,
    counts_to_angle,
    lvdt_measure,
    quantize_angle,
)

U_MAX = 5.0


def _actions(seed: int, n: int) -> np.ndarray:
    """Varying voltages: a slow ramp with jumps, some beyond the amplifier's 5 V."""
    r = np.random.default_rng(seed)
    base = np.repeat(r.uniform(-2.0, 6.5, n // 20 + 1), 20)[:n]
    return (base + r.normal(0.0, 0.5, n)).astype(np.float32).reshape(n, 1)


def _wrap(theta: np.ndarray) -> np.ndarray:
    return np.mod(theta + np.pi, 2 * np.pi) - np.pi


def _in_box(values: list[float], space: gym.spaces.Box) -> np.ndarray:
    return np.clip(np.asarray(values, dtype=np.float32), space.low, space.high)


def _episode(env_id: str, mode: str, seed: int, steps: int, **kw):
    """Observations and true states of one seeded episode (stops early when it ends)."""
    env = gym.make(env_id, normalize_action=False, observation=mode, **kw)
    obs, _ = env.reset(seed=seed)
    system = env.unwrapped.batch.system
    states, observations, volts = [system.Y[0].copy()], [obs], []
    for a in _actions(seed, steps):
        obs, _, term, trunc, info = env.step(a)
        states.append(system.Y[0].copy())
        observations.append(obs)
        volts.append(info["voltage"])
        if term or trunc:
            break
    return env, np.array(states), np.array(observations), np.array(volts)


@pytest.mark.parametrize("env_id", ["drillgym/Torsional-v0", "drillgym/Coupled-v0"])
def test_sensor_observation_from_the_true_state(env_id: str) -> None:
    seed = 3
    env, Y, obs, volts = _episode(env_id, "sensors", seed, 300)
    assert len(volts) >= 250 and np.ptp(volts) > 3.0 and volts.max() == U_MAX  # varied, clipped voltages ran
    o: EnvOptions = env.unwrapped.options
    rng = seeding.np_random(seed)[0]
    omega_ref, _ = SpeedTrackingTask(o).sample(rng)  # the episode's draws come first, then the sensor noise
    noise = rng.standard_normal((len(volts), 2))
    qu, ql = quantize_angle(Y[:, 0], o.counts_per_rev), quantize_angle(Y[:, 1], o.counts_per_rev)
    c, s = np.cos(Y[:, 0]), np.sin(Y[:, 0])
    xm, ym = lvdt_measure(Y[:, 4] * c - Y[:, 5] * s, Y[:, 4] * s + Y[:, 5] * c)  # no measurement effect
    xm[1:] += o.lvdt_noise_std * noise[:, 0]  # the reset observation is noise-free
    ym[1:] += o.lvdt_noise_std * noise[:, 1]
    a = np.exp(-o.control_dt / o.velocity_filter_tau)
    wu = wl = 0.0
    for k in range(len(obs)):
        if k:
            wu = a * wu + (1.0 - a) * (qu[k] - qu[k - 1]) / o.control_dt
            wl = a * wl + (1.0 - a) * (ql[k] - ql[k - 1]) / o.control_dt
        lvdt = [1e3 * xm[k], 1e3 * ym[k]] if o.lateral else []
        u = volts[k - 1] if k else 0.0
        row = [_wrap(qu[k]), _wrap(ql[k]), ql[k] - qu[k], wu, wl, *lvdt, u, omega_ref]
        np.testing.assert_array_equal(obs[k], _in_box(row, env.observation_space), err_msg=f"period {k}")
    if o.lateral:
        assert np.std(obs[1:, 5] - 1e3 * (xm[1:] - o.lvdt_noise_std * noise[:, 0])) > 1e-3  # noise is present


@pytest.mark.parametrize("env_id", ["drillgym/Torsional-v0", "drillgym/Coupled-v0"])
def test_motor_observation_from_the_true_state(env_id: str) -> None:
    H = 6
    env, Y, obs, volts = _episode(env_id, "motor", 5, 300, motor_history=H)
    assert len(volts) >= 250
    o = env.unwrapped.options
    q = quantize_angle(Y[:, 0], o.counts_per_rev)
    inc = np.diff(q) / o.control_dt
    omega_ref = obs[0, 2 * H]
    for k in range(len(obs)):
        recent_inc = list(inc[:k][::-1][:H]) + [0.0] * max(0, H - k)  # newest first, zeros before the start
        recent_u = list(volts[:k][::-1][:H]) + [0.0] * max(0, H - k)
        row = _in_box([*recent_inc, *recent_u, omega_ref], env.observation_space)
        np.testing.assert_array_equal(obs[k], row, err_msg=f"period {k}")
    assert np.abs(obs[1:, 0]).max() > 0.5  # increments of a turning disc, not all zero


@pytest.mark.parametrize("env_id, mode", [("drillgym/Coupled-v0", "sensors"), ("drillgym/Torsional-v0", "motor")])
def test_vector_env_rows_equal_single_envs_exactly(env_id: str, mode: str) -> None:
    # 127-step episodes: under next-step autoreset a rig's 128th noise period falls on the step
    # before its reset, where it must draw nothing (the single env never takes that step)
    n, steps, kw = 3, 300, dict(observation=mode, episode_duration=1.27)
    venv = make_vec(env_id, n, normalize_action=False, **kw)
    vobs, _ = venv.reset(seed=20)
    actions = np.stack([_actions(i, steps) for i in range(n)], axis=1)
    rows = [vobs]
    for a in actions:
        rows.append(venv.step(a)[0])
    rows = np.array(rows)
    for i in range(n):
        env = gym.make(env_id, normalize_action=False, **kw)
        expect, done = [env.reset(seed=20 + i)[0]], False
        for a in actions[:, i]:
            if done:
                obs, _ = env.reset()
                done = False
            else:
                obs, _, term, trunc, _ = env.step(a)
                done = term or trunc
            expect.append(obs)
        np.testing.assert_array_equal(rows[:, i], np.array(expect), err_msg=f"rig {i}")


def _random_walk(n: int, steps: int, seed: int) -> np.ndarray:
    """States (steps, n, 9) with turning discs and a whirling lower disc (only the observed entries)."""
    r = np.random.default_rng(seed)
    Y = np.zeros((steps, n, 9))
    Y[:, :, 0] = np.cumsum(r.normal(0.05, 0.05, (steps, n)), axis=0)
    Y[:, :, 1] = Y[:, :, 0] + r.normal(0.0, 0.5, (steps, n))
    Y[:, :, 4:6] = 2e-3 * r.standard_normal((steps, n, 2))
    return Y


def test_readings_path_equals_simulated_path() -> None:
    """from_readings (hardware twin, agents) on the simulated readings gives the observe() result;
    the numpy LVDT path of SimulatedSensors draws the same noise as the compiled one."""
    n, steps = 3, 300
    o = EnvOptions.from_kwargs(configuration="coupled", observation="sensors")
    sim, hw = SensorObservation(n, o), SensorObservation(n, o)
    msim, mhw = (
        MotorObservation(n, EnvOptions.from_kwargs(configuration="coupled", observation="motor")) for _ in range(2)
    )
    states = _random_walk(n, steps, 1)
    rngs_sim = [np.random.default_rng(i) for i in range(n)]
    rngs_hw = [np.random.default_rng(i) for i in range(n)]
    idx, ref = np.arange(n), np.array([1.0, 4.0, 7.0])
    for model, rngs in ((sim, rngs_sim), (hw, rngs_hw), (msim, None), (mhw, None)):
        model.reset(idx, states[0], rngs or [None] * n)
        np.testing.assert_array_equal(model.initial(idx, states[0], ref)[:, -1], ref)
    out_sim, out_hw = (np.zeros((n, sim.dim), dtype=np.float32) for _ in range(2))
    mout_sim, mout_hw = (np.zeros((n, msim.dim), dtype=np.float32) for _ in range(2))
    for k in range(1, steps):
        Y, u = states[k], np.full(n, np.sin(0.1 * k) * 6.0)
        sim.observe(Y, u, ref, out_sim, rngs_sim)
        tu, tl = hw.sensors.encoders(Y)
        xm, ym = hw.sensors.lvdts(Y, rngs_hw)
        hw.from_readings(tu, tl, xm, ym, u, ref, out_hw)
        np.testing.assert_array_equal(out_sim, out_hw, err_msg=f"sensors, period {k}")
        msim.observe(Y, u, ref, mout_sim, None)
        mhw.from_readings(quantize_angle(Y[:, 0], o.counts_per_rev), u, ref, mout_hw)
        np.testing.assert_array_equal(mout_sim, mout_hw, err_msg=f"motor, period {k}")
    assert np.abs(out_sim[:, 3]).max() > 1.0 and np.ptp(mout_sim[0, msim.H : 2 * msim.H]) > 1.0  # speeds, voltages
    np.testing.assert_array_equal(sim.est_u.omega, hw.est_u.omega)  # the estimators' state is shared
    X, Yf = fixed_frame_lateral(states[-1])
    assert 0 < np.abs(out_sim[:, 5] - 1e3 * X).max() < 0.05  # mm: noise of a few um


def test_from_readings_takes_scalars_and_names_bad_shapes() -> None:
    o = EnvOptions.from_kwargs(configuration="torsional", observation="sensors")
    model, out = SensorObservation(1, o), np.zeros((1, 7), dtype=np.float32)
    model.reset(np.arange(1), np.zeros((1, 9)), [None])
    model.from_readings(0.01, 0.02, None, None, 2.0, 3.0, out)
    assert out[0, 2] == pytest.approx(0.01) and out[0, 3] == pytest.approx(1.0 - np.exp(-0.5), rel=1e-6)
    with pytest.raises(ValueError, match="theta_l"):
        model.from_readings(np.zeros(1), np.zeros(2), None, None, np.zeros(1), np.ones(1), out)
    with pytest.raises(ValueError, match="out"):
        model.from_readings(np.zeros(1), np.zeros(1), None, None, np.zeros(1), np.ones(1), np.zeros((1, 7)))


def test_measurement_formulas_are_unchanged() -> None:
    r = np.random.default_rng(0)
    theta = np.concatenate([r.uniform(-1e4, 1e4, 10000), counts_to_angle(np.arange(-500, 500)), [0.0, -0.0]])
    for cpr in (8000, 100, 7):
        q = quantize_angle(theta, cpr)
        ref = counts_to_angle(angle_to_counts(theta, cpr), cpr)
        np.testing.assert_array_equal(q.view(np.int64), ref.view(np.int64))  # bit for bit, -0.0 -> 0.0 included
    np.testing.assert_array_equal(quantize_angle(theta, 0), theta)
    est = EncoderVelocityEstimator(2, 0.01, 0.02)
    est.reset(np.array([0.0, 1.0]))
    est.update(np.array([0.1, 0.9]))
    w = est.update(np.array([0.3, 0.9])).copy()
    a = np.exp(-0.5)
    w1 = (1 - a) * np.array([10.0, -10.0])
    np.testing.assert_allclose(w, a * w1 + (1 - a) * np.array([20.0, 0.0]), rtol=1e-12)
