"""The vectorised env: equals N single envs, Gymnasium autoreset semantics, SB3 adapter and PPO."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import drillgym  # noqa: F401
from drillgym.envs import DrillVectorEnv, make_vec
from drillgym.envs.sb3 import SB3VecEnvAdapter, make_sb3_vec

N = 4


@pytest.mark.parametrize(
    "env_id, mode",
    [("drillgym/Torsional-v0", "full"), ("drillgym/Coupled-v0", "sensors"), ("drillgym/Lateral-v0", "motor")],
)
def test_vector_env_matches_single_envs_with_next_step_autoreset(env_id: str, mode: str) -> None:
    opts = dict(observation=mode, episode_duration=0.5, randomize=0.05)
    venv = make_vec(env_id, N, normalize_action=False, **opts)
    envs = [gym.make(env_id, normalize_action=False, **opts) for _ in range(N)]
    vobs, vinfo = venv.reset(seed=10)
    for i, env in enumerate(envs):
        obs, info = env.reset(seed=10 + i)
        np.testing.assert_allclose(vobs[i], obs, atol=1e-6)
        assert vinfo["omega_ref"][i] == info["omega_ref"]
    actions = np.random.default_rng(0).uniform(-5, 5, (130, N, 1)).astype(np.float32)
    needs_reset = [False] * N
    n_resets = 0
    for a in actions:
        vobs, vrew, vterm, vtrunc, vinfo = venv.step(a)
        for i, env in enumerate(envs):
            if needs_reset[i]:  # next-step autoreset: reset obs, reward 0, not done
                obs, info = env.reset()
                rew, term, trunc = 0.0, False, False
                n_resets += 1
            else:
                obs, rew, term, trunc, info = env.step(a[i])
            np.testing.assert_allclose(vobs[i], obs, atol=1e-5)
            assert vrew[i] == pytest.approx(rew, abs=1e-9)
            assert (vterm[i], vtrunc[i]) == (term, trunc)
            assert vinfo["omega_l"][i] == pytest.approx(info["omega_l"], abs=1e-9)
            needs_reset[i] = term or trunc
    assert n_resets == 2 * N  # two episode ends of 50 steps in 130 steps


def test_same_step_autoreset_reports_final_observation() -> None:
    venv = DrillVectorEnv(3, "torsional", episode_duration=0.1, autoreset_mode=AutoresetMode.SAME_STEP)
    venv.reset(seed=0)
    for _ in range(9):
        _, _, _, trunc, info = venv.step(np.full(3, 2.0))
        assert not trunc.any() and "final_obs" not in info
    obs, rew, term, trunc, info = venv.step(np.full(3, 2.0))
    assert trunc.all() and info["_final_obs"].all()
    final = np.stack(info["final_obs"])
    assert np.all(final[:, 3] == 2.0)  # last applied voltage in the final observation
    assert np.all(obs[:, 3] == 0.0)  # already reset
    assert np.all(info["final_info"]["time"] == pytest.approx(0.1))


def test_vector_env_errors_and_spaces() -> None:
    venv = make_vec("drillgym/Coupled-v0", 5, normalize_action=False)
    assert venv.observation_space.shape == (5, 9) and venv.action_space.shape == (5, 1)
    venv.reset(seed=0)
    bad = np.full(5, 1.0)
    bad[3] = np.nan
    with pytest.raises(ValueError, match="env 3"):
        venv.step(bad)
    with pytest.raises(ValueError, match="5 voltages"):
        venv.step(np.ones(4))
    with pytest.raises(ValueError, match="unknown drillgym environment"):
        make_vec("drillgym/Nope-v0", 2)


def test_gymnasium_make_vec_uses_the_batched_env() -> None:
    venv = gym.make_vec("drillgym/Torsional-v0", num_envs=3, vectorization_mode="vector_entry_point")
    assert isinstance(venv.unwrapped, DrillVectorEnv)
    obs, _ = venv.reset(seed=1)
    assert obs.shape == (3, 5)


def test_sb3_adapter_steps_and_resets() -> None:
    venv = make_sb3_vec("drillgym/Torsional-v0", 3, episode_duration=0.05)
    venv.seed(4)
    obs = venv.reset()
    assert obs.shape == (3, 5)
    for _ in range(5):
        obs, rew, dones, infos = venv.step(np.full((3, 1), 1.0, dtype=np.float32))
    assert dones.all() and rew.dtype == np.float32
    assert all(info["TimeLimit.truncated"] and info["terminal_observation"].shape == (5,) for info in infos)
    with pytest.raises(ValueError, match="SAME_STEP"):
        SB3VecEnvAdapter(make_vec("drillgym/Torsional-v0", 2, normalize_action=False))


def test_ppo_learns_a_few_hundred_steps_on_the_vector_env() -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    venv = VecMonitor(make_sb3_vec("drillgym/Torsional-v0", 4, normalize_action=True, episode_duration=0.5))
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=512)
    assert model.num_timesteps >= 512
    assert len(model.ep_info_buffer) > 0  # episodes ended and were recorded through the adapter
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (4, 1)
