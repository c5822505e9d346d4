"""RL conventions of the agents: rl-zoo3-clean hyperparameter files, evaluation callback with the best
model, the learning_starts warning, exported observation normalisation, results over several seeds."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.vec_env import VecNormalize

import drillgym  # noqa: F401
from agents.export import ExportedPolicy
from agents.hyperparams import HYPERPARAMS_DIR, STRUCTURE_KEYS, STRUCTURE_SECTION, ZOO_KEYS, load_hyperparams
from agents.seeds import NOT_HELD, iqm, iqm_ci, plot_learning_curves, write_results
from agents.train import train
from drillgym.envs import make_sb3_vec

FAST = {"n_envs": 4, "env_kwargs": {"episode_duration": 0.5}}
CLASSES = {"ppo": PPO, "sac": SAC, "td3": TD3}


def _files():
    return sorted(HYPERPARAMS_DIR.glob("*.yml"))


@pytest.mark.parametrize("path", _files(), ids=lambda p: p.name)
def test_hyperparameter_files_instantiate_the_algorithm_unchanged(path: Path) -> None:
    """What rl-zoo3 does with an entry: pop its own keys, pass the rest to the algorithm."""
    algo = path.stem.split("_")[0]
    data = yaml.safe_load(path.read_text())
    entries = {k: v for k, v in data.items() if k != STRUCTURE_SECTION}
    assert entries
    for env_id, entry in entries.items():
        assert not set(entry) & set(STRUCTURE_KEYS), f"{path.name} {env_id}: drillgym keys among the algorithm's"
        kwargs = {k: v for k, v in entry.items() if k not in ZOO_KEYS}
        if isinstance(kwargs.get("policy_kwargs"), str):
            kwargs["policy_kwargs"] = eval(kwargs["policy_kwargs"])  # rl-zoo3 evaluates the string
        env = gym.make(env_id, **entry.get("env_kwargs", {}))
        if algo == "recurrentppo":
            from sb3_contrib import RecurrentPPO as cls
        else:
            cls = CLASSES[algo]
        cls(entry["policy"], env, _init_setup_model=False, **kwargs)  # unknown keywords raise here
        env.close()


def test_structure_section_is_merged_and_a_misplaced_key_named(tmp_path) -> None:
    hp = load_hyperparams("ppo", "drillgym/Torsional-v0", HYPERPARAMS_DIR / "ppo_residual.yml")
    assert hp["residual"] == 1.5 and hp["normalize_reward"] and not hp["normalize_obs"]
    plain = load_hyperparams("ppo", "drillgym/Torsional-v0")
    assert "residual" not in plain and plain["privileged_critic"] and plain["policy_kwargs"]["log_std_init"] == -0.5
    assert plain["normalize_reward"] and not plain["normalize_obs"]
    bad = tmp_path / "bad.yml"
    bad.write_text("drillgym/Torsional-v0: {policy: MlpPolicy, residual: 1.0}\n")
    with pytest.raises(ValueError, match="put them under the top-level section 'drillgym"):
        load_hyperparams("ppo", "drillgym/Torsional-v0", bad)


def test_sb3_adapter_is_public_and_normalised() -> None:
    venv = make_sb3_vec("drillgym/Torsional-v0", 2, episode_duration=0.05)
    assert venv.action_space.high[0] == 1.0 and venv.num_envs == 2
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=16, n_epochs=1, seed=0)
    model.learn(16)
    assert model.num_timesteps == 16


def test_timesteps_below_learning_starts_warn(tmp_path) -> None:
    with pytest.warns(UserWarning, match="learning_starts"):
        train(
            "drillgym/Torsional-v0",
            "sac",
            tmp_path,
            timesteps=40,
            progress=False,
            tensorboard=False,
            overrides={**FAST, "learning_starts": 100, "buffer_size": 500},
            export=False,
        )


def test_evaluation_keeps_the_best_model_and_normalisation_is_exported(tmp_path) -> None:
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path,
        timesteps=256,
        seed=0,
        progress=False,
        tensorboard=False,
        overrides={**FAST, "n_steps": 16, "batch_size": 32, "normalize_obs": True, "privileged_critic": False},
        eval_every=64,
        eval_envs=2,
    )
    with np.load(tmp_path / "evaluations.npz") as z:
        assert len(z["timesteps"]) >= 3 and z["results"].shape[1] == 2
    for f in ("best/best_model.zip", "best/policy.npz"):
        assert (tmp_path / f).is_file(), f
    policy = ExportedPolicy.load(res.policy_path)
    assert policy.obs_norm is not None  # standardised observations: the statistics travel with the policy
    stats = VecNormalize.load(
        str(tmp_path / "checkpoints" / "latest_vecnormalize.pkl"),
        make_sb3_vec("drillgym/Torsional-v0", 1, observation="motor"),
    )
    rng = np.random.default_rng(0)
    obs = rng.normal(0.0, 3.0, (50, policy.obs_dim)).astype(np.float32)
    expected, _ = res.model.predict(stats.normalize_obs(obs), deterministic=True)
    np.testing.assert_allclose(policy.act(obs), expected, atol=1e-5)


def test_iqm_and_bootstrap_interval() -> None:
    assert iqm([1.0, 2.0, 3.0, 4.0]) == pytest.approx(2.5)
    assert iqm([0.0, 2.0, 2.0, 2.0, 100.0]) == pytest.approx(2.0)  # the outliers are trimmed
    lo, hi = iqm_ci([2.0, 2.5, 3.0, 2.0, 3.5])
    assert 2.0 <= lo <= iqm([2.0, 2.5, 3.0, 2.0, 3.5]) <= hi <= 3.5
    assert np.isnan(iqm_ci([2.0])[0])


def test_seed_results_table_and_curves(tmp_path) -> None:
    rows = [
        {"seed": s, "timesteps": 100, "wall_time": 10.0 + s, "lowest_held": v, "final_reward": -s}
        for s, v in zip(range(4), [2.0, 2.5, float("nan"), 3.0])
    ]
    summary = write_results(rows, tmp_path)
    held = summary.aggregates["lowest_held"]
    assert held["median"] == pytest.approx((2.5 + 3.0) / 2)  # none held counts as NOT_HELD, above the grid
    assert held["iqm"] == pytest.approx(iqm([2.0, 2.5, 3.0, NOT_HELD]))
    text = (tmp_path / "results.md").read_text()
    assert "IQM" in text and "95 % CI" in text and text.count("\n| ") >= 4
    assert (tmp_path / "results.csv").read_text().splitlines()[0].startswith("seed,")
    for s in range(2):
        d = tmp_path / f"seed_{s}"
        d.mkdir()
        np.savez(d / "evaluations.npz", timesteps=np.array([10, 20]), results=np.array([[-3.0, -2.0], [-1.0, -0.5]]))
    assert plot_learning_curves([tmp_path / "seed_0", tmp_path / "seed_1"], tmp_path / "c.png").stat().st_size > 1000


def test_privileged_critic_trains_and_the_deployed_actor_ignores_the_privileged_entries(tmp_path) -> None:
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path,
        timesteps=128,
        seed=0,
        progress=False,
        tensorboard=False,
        overrides={**FAST, "n_steps": 16, "batch_size": 32, "privileged_critic": True},
    )
    model = res.model
    assert model.observation_space.shape == (36,) and model.policy.actor_dim == 33
    policy = ExportedPolicy.load(res.policy_path)
    assert policy.obs_dim == 33 and policy.layers[0][0].shape[0] == 33
    stats = VecNormalize.load(str(tmp_path / "checkpoints" / "latest_vecnormalize.pkl"), model.get_env())
    rng = np.random.default_rng(1)
    obs = rng.normal(0.0, 3.0, (40, 36)).astype(np.float32)
    other = obs.copy()
    other[:, 33:] = rng.normal(0.0, 3.0, (40, 3))  # the critic's entries change, the action must not
    a, _ = model.predict(stats.normalize_obs(obs), deterministic=True)
    b, _ = model.predict(stats.normalize_obs(other), deterministic=True)
    np.testing.assert_allclose(a, b, atol=1e-6)
    np.testing.assert_allclose(policy.act(obs[:, :33]), a, atol=1e-5)
    v1 = model.policy.predict_values(model.policy.obs_to_tensor(stats.normalize_obs(obs))[0])
    v2 = model.policy.predict_values(model.policy.obs_to_tensor(stats.normalize_obs(other))[0])
    assert not np.allclose(v1.detach().numpy(), v2.detach().numpy())  # the critic reads them
