"""Gymnasium/SB3 API conformance, options and input validation of the drillgym environments."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import drillgym  # noqa: F401  (registers the ids)
from drillgym.envs import ENV_IDS, EnvOptions

MODES = ("full", "sensors", "motor")


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
@pytest.mark.parametrize("mode", MODES)
def test_env_checkers_pass(env_id: str, mode: str) -> None:
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*symmetric and normalized.*")
        check_env(gym.make(env_id, observation=mode).unwrapped)
        sb3_check_env(gym.make(env_id, observation=mode, normalize_action=True).unwrapped, warn=True)


def test_spaces_and_layouts() -> None:
    env = gym.make("drillgym/Torsional-v0")  # RL convention: normalised actions by default
    assert env.action_space.shape == (1,) and env.action_space.low[0] == -1 and env.action_space.high[0] == 1
    volts = gym.make("drillgym/Torsional-v0", normalize_action=False)
    assert volts.action_space.low[0] == -5 and volts.action_space.high[0] == 5
    assert env.unwrapped.observation_names == ("omega_u", "omega_l", "alpha", "u_prev", "omega_ref")
    coupled = gym.make("drillgym/Coupled-v0", observation="sensors").unwrapped
    assert coupled.observation_names[5:7] == ("X_meas", "Y_meas") and coupled.observation_space.shape == (9,)
    motor = gym.make("drillgym/Lateral-v0", observation="motor", motor_history=5).unwrapped
    assert motor.observation_space.shape == (11,)
    norm = gym.make("drillgym/Torsional-v0", normalize_action=True)
    assert norm.action_space.low[0] == -1 and norm.action_space.high[0] == 1


def test_spec_gives_the_episode_length_and_episodes_truncate_there() -> None:
    env = gym.make("drillgym/Torsional-v0", episode_duration=0.5, control_dt=0.01)
    assert env.spec.max_episode_steps == 50 and env.spec.kwargs["normalize_action"] is True
    assert gym.make("drillgym/Torsional-v0").spec.max_episode_steps == 3000
    env.reset(seed=0)
    ends = [env.step(np.array([0.5]))[3] for _ in range(50)]
    assert not any(ends[:-1]) and ends[-1]
    vec = gym.make_vec("drillgym/Torsional-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert vec.single_action_space.high[0] == 1


def test_reset_observation_starts_at_rest_with_winding_and_target() -> None:
    env = gym.make("drillgym/Torsional-v0", alpha0_range=(0.4, 0.4), omega_ref=3.0)
    obs, info = env.reset(seed=0)
    np.testing.assert_allclose(obs, [0.0, 0.0, 0.4, 0.0, 3.0], atol=1e-6)
    assert info["stuck"] and info["omega_ref"] == 3.0
    assert info["friction_torque"] == pytest.approx(-0.0775 * 0.4)  # holding torque: Tfl = -k_theta alpha0


@pytest.mark.parametrize("bad", [np.array([np.nan], dtype=np.float32), [np.inf], float("nan")])
def test_non_finite_action_raises(bad) -> None:
    env = gym.make("drillgym/Torsional-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(bad)


def test_wrong_action_size_raises() -> None:
    env = gym.make("drillgym/Torsional-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="one voltage"):
        env.step(np.array([1.0, 2.0]))


def test_actions_are_clipped_like_the_amplifier() -> None:
    env = gym.make("drillgym/Torsional-v0", normalize_action=False).unwrapped
    env.reset(seed=0)
    assert env.step(np.array([12.0]))[4]["voltage"] == 5.0
    assert env.step(np.array([-7.0]))[4]["voltage"] == -5.0
    norm = gym.make("drillgym/Torsional-v0", normalize_action=True).unwrapped
    norm.reset(seed=0)
    assert norm.step(np.array([0.5]))[4]["voltage"] == pytest.approx(2.5)
    assert norm.step(np.array([3.0]))[4]["voltage"] == 5.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"observation": "camera"}, "observation"),
        ({"bogus": 1}, "bogus"),
        ({"control_dt": 0.01, "dt": 0.003}, "dt"),
        ({"omega_ref_range": (5.0, 2.0)}, "omega_ref_range"),
        ({"randomize": 1.5}, "randomize"),
        ({"randomize_names": ("Ts", "nope")}, "nope"),
        ({"reward": {"track": -1.0}}, "track"),
        ({"configuration": "upper"}, "configuration"),
    ],
)
def test_bad_options_name_the_option(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        EnvOptions.from_kwargs(**kwargs)


def test_same_seed_same_trajectory_and_other_seed_differs() -> None:
    def run(seed: int) -> np.ndarray:
        env = gym.make("drillgym/Coupled-v0", observation="sensors", randomize=0.05)
        obs = [env.reset(seed=seed)[0]]
        actions = np.random.default_rng(1).uniform(-5, 5, (200, 1)).astype(np.float32)
        for a in actions:
            obs.append(env.step(a)[0])
        return np.array(obs)

    a, b, c = run(7), run(7), run(8)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
