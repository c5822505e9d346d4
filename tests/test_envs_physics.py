"""The environments on the physics core: agreement with simulate(), stick-slip, limits, randomisation."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import drillgym
from drillgym import RigParams, simulate
from drillgym.envs.task import StickSlipMonitor


def _run_constant(env_id: str, u: float, steps: int, **options) -> tuple[list[dict], list[np.ndarray]]:
    env = gym.make(env_id, normalize_action=False, **options).unwrapped
    obs, info = env.reset(seed=0)
    infos, observations = [info], [obs]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(np.array([u], dtype=np.float32))
        assert not (terminated or truncated)
        infos.append(info)
        observations.append(obs)
    return infos, observations


def test_constant_1V_from_rest_gives_stick_slip_like_the_core() -> None:
    alpha0 = 0.3
    infos, obs = _run_constant(
        "drillgym/Torsional-v0", 1.0, 3000, alpha0_range=(alpha0, alpha0), omega_ref=2.0, episode_duration=40.0
    )
    wl = np.array([i["omega_l"] for i in infos])
    stuck = np.array([i["stuck"] for i in infos])
    # same kernel, same step: the env is the core
    ref = simulate("torsional", 1.0, 30.0, dt=0.01, alpha0=alpha0)
    np.testing.assert_allclose(wl, ref.omega_l, atol=1e-9)
    np.testing.assert_array_equal(stuck, ref.stick_l > 0.5)
    # and the core's 1 ms reference
    fine = simulate("torsional", 1.0, 30.0, dt=1e-3, alpha0=alpha0)
    np.testing.assert_allclose(wl, fine.omega_l[::10], atol=1e-5)
    # stick-slip: the disc sticks for a large part of the time, slips up to ~6 rad/s, SSI well above 1
    late = slice(1000, None)
    assert 0.3 < stuck[late].mean() < 0.7
    assert wl.max() > 5.0
    assert infos[-1]["stick_slip_severity"] > 1.0
    np.testing.assert_allclose([o[2] for o in obs], fine.alpha[::10], atol=1e-4)  # winding in the observation


def test_steady_rotation_above_the_fold_has_no_stick_slip() -> None:
    # R7: above the fold (3.9 V and up) the torsional rig settles to steady rotation from rest
    # (a lightly damped torsional oscillation decays around 8.7 rad/s)
    infos, _ = _run_constant("drillgym/Torsional-v0", 5.0, 2999, omega_ref=6.0)
    wl = np.array([i["omega_l"] for i in infos])
    assert not any(i["stuck"] for i in infos[-2000:])
    assert abs(wl[-500:].mean() - 8.73) < 0.1
    ssi = [i["stick_slip_severity"] for i in infos]
    assert ssi[1000] > ssi[2000] > ssi[-1] and ssi[-1] < 0.05


def test_stick_slip_severity_matches_its_definition() -> None:
    # window 1 s at 10 ms = 100 samples in 10 blocks: the SSI covers the last 91..100 samples
    monitor = StickSlipMonitor(1, window=1.0, control_dt=0.01)
    t = np.arange(357) * 0.01
    w = 2.0 + np.sin(2 * np.pi * 0.7 * t) + 0.3 * np.sin(2 * np.pi * 3.1 * t)
    for wk in w:
        ssi = monitor.update(np.array([wk]))[0]
    candidates = [np.ptp(w[-m:]) / (2 * abs(w[-m:].mean())) for m in range(91, 101)]
    assert np.isclose(ssi, candidates, rtol=1e-12).any()
    # at rest: 0
    rest = StickSlipMonitor(1, window=1.0, control_dt=0.01)
    assert rest.update(np.zeros(1))[0] == 0.0


def test_env_reports_the_monitor_severity() -> None:
    infos, _ = _run_constant("drillgym/Torsional-v0", 1.0, 800, alpha0_range=(0.0, 0.0), ssi_window=5.0)
    monitor = StickSlipMonitor(1, window=5.0, control_dt=0.01)
    for info in infos[1:]:
        ssi = monitor.update(np.array([info["omega_l"]]))[0]
        assert info["stick_slip_severity"] == pytest.approx(ssi, rel=1e-12, abs=1e-12)


def test_over_speed_terminates() -> None:
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, max_speed=3.0, omega_ref=2.0).unwrapped
    env.reset(seed=0)
    for _ in range(1000):
        _, _, terminated, truncated, info = env.step(np.array([5.0]))
        if terminated:
            break
    assert terminated and not truncated
    assert abs(env.batch.system.omega_u[0]) > 3.0 or abs(info["omega_l"]) > 3.0


def test_lateral_displacement_terminates_coupled() -> None:
    env = gym.make("drillgym/Coupled-v0", normalize_action=False, max_lateral=1e-3).unwrapped
    env.reset(seed=0)
    for _ in range(2000):
        obs, _, terminated, _, _ = env.step(np.array([5.0]))
        if terminated:
            break
    assert terminated
    assert np.hypot(obs[3], obs[4]) >= 1.0 - 1e-3  # X, Y in mm


def test_truncation_at_episode_duration() -> None:
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, episode_duration=0.5).unwrapped
    env.reset(seed=0)
    flags = [env.step(np.array([0.0]))[3] for _ in range(50)]
    assert flags[-1] and not any(flags[:-1])


def test_reward_penalises_tracking_error_stick_and_effort() -> None:
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, omega_ref=4.0, alpha0_range=(0.0, 0.0)).unwrapped
    env.reset(seed=0)
    _, r, _, _, info = env.step(np.array([0.1]))  # below the breakaway voltage: stays stuck
    assert info["stuck"]
    expected = -(1.0 * 1.0 + 0.5 + 0.01 * (0.1 / 5) ** 2 + 0.05 * (0.1 / 5) ** 2)
    assert r == pytest.approx(expected)


def test_domain_randomisation_draws_parameters_per_episode() -> None:
    env = gym.make(
        "drillgym/Torsional-v0", normalize_action=False, randomize=0.1, randomize_names=("Ts", "ktheta")
    ).unwrapped
    base = RigParams().to_vector()
    env.reset(seed=1)
    p1 = env.batch.system.params_matrix[0].copy()
    env.reset()
    p2 = env.batch.system.params_matrix[0].copy()
    changed = np.flatnonzero(p1 != base)
    assert set(changed) == {drillgym.params.IDX.Ts, drillgym.params.IDX.ktheta}
    assert np.all(np.abs(p1[changed] / base[changed] - 1) <= 0.1)
    assert not np.array_equal(p1, p2)
    env.reset(seed=1)
    np.testing.assert_array_equal(env.batch.system.params_matrix[0], p1)


def test_sensor_observation_is_quantized_and_noisy() -> None:
    env = gym.make(
        "drillgym/Coupled-v0", normalize_action=False, observation="sensors", counts_per_rev=100, lvdt_noise_std=5e-6
    ).unwrapped
    env.reset(seed=0)
    for _ in range(200):
        obs, *_ = env.step(np.array([3.0]))
    step = 2 * np.pi / 100
    alpha_meas = obs[2]
    assert abs(alpha_meas / step - round(alpha_meas / step)) < 1e-3  # difference of two quantized angles
    X, Y = env.batch.system.lateral_fixed
    err = np.hypot(obs[5] - 1e3 * X[0], obs[6] - 1e3 * Y[0])
    assert 0 < err < 0.05  # mm: a few micrometres of noise
    assert abs(obs[4] - env.batch.system.omega_l[0]) < 1.5  # filtered speed estimate near the truth
