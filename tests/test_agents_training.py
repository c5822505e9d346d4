"""Agents: training end to end (save, load, resume), export equivalence, hyperparameter files, errors."""

import sys

import numpy as np
import pytest
import yaml
from stable_baselines3 import PPO, SAC, TD3

import controllers
from agents.export import ExportedPolicy
from agents.hyperparams import load_hyperparams, parse_overrides
from agents.train import train

FAST = {"n_envs": 4, "env_kwargs": {"episode_duration": 1.0}}
OFF_POLICY = {**FAST, "learning_starts": 64, "buffer_size": 2000, "batch_size": 32}


def _random_obs(policy: ExportedPolicy, n: int = 200) -> np.ndarray:
    rng = np.random.default_rng(0)
    obs = rng.normal(0.0, 2.0, (n, policy.obs_dim)).astype(np.float32)
    obs[:, -1] = rng.uniform(2.0, 8.0, n)  # omega_ref
    return obs


def test_sac_trains_saves_loads_and_resumes(tmp_path):
    res = train(
        "drillgym/Torsional-v0",
        "sac",
        tmp_path,
        obs="motor",
        timesteps=300,
        seed=3,
        overrides=OFF_POLICY,
        progress=False,
        checkpoint_every=100,
    )
    assert res.timesteps == 300
    for f in (
        "model.zip",
        "policy.npz",
        "config.yml",
        "checkpoints/latest.zip",
        "checkpoints/latest_replay_buffer.pkl",
    ):
        assert (tmp_path / f).is_file(), f
    assert any((tmp_path / "tb").rglob("events.out.tfevents*"))  # TensorBoard log
    cfg = yaml.safe_load((tmp_path / "config.yml").read_text())
    assert cfg["seed"] == 3 and cfg["hyperparams"]["env_kwargs"]["observation"] == "motor"
    assert cfg["hyperparams"]["env_kwargs"]["randomize"] > 0  # domain randomisation on
    model = SAC.load(tmp_path / "model.zip")
    assert model.num_timesteps == 300 and model.observation_space.shape == (33,)
    # resume continues the step count from the checkpoint up to the new total
    res2 = train(
        "drillgym/Torsional-v0",
        "sac",
        tmp_path,
        obs="motor",
        timesteps=400,
        seed=3,
        overrides=OFF_POLICY,
        progress=False,
        resume=True,
    )
    assert res2.timesteps == 400
    assert SAC.load(tmp_path / "model.zip").num_timesteps == 400


@pytest.mark.parametrize(
    "algo,cls,extra",
    [
        ("sac", SAC, OFF_POLICY),
        ("td3", TD3, OFF_POLICY),
        ("ppo", PPO, {**FAST, "n_steps": 32, "batch_size": 64, "privileged_critic": False}),
    ],
)
def test_exported_policy_matches_sb3(tmp_path, algo, cls, extra):
    train(
        "drillgym/Torsional-v0",
        algo,
        tmp_path,
        obs="motor",
        timesteps=256,
        seed=0,
        overrides=extra,
        progress=False,
        tensorboard=False,
    )
    model = cls.load(tmp_path / "model.zip", device="cpu")
    policy = ExportedPolicy.load(tmp_path / "policy.npz")
    obs = _random_obs(policy)
    expected, _ = model.predict(obs, deterministic=True)
    np.testing.assert_allclose(policy.act(obs), expected, atol=1e-5)
    np.testing.assert_allclose(policy.act(obs[0]), expected[0], atol=1e-5)  # single observation


def test_hyperparameter_files_are_rl_zoo_style():
    for algo in ("ppo", "sac", "td3", "recurrentppo"):
        hp = load_hyperparams(algo, "drillgym/Torsional-v0")
        assert hp["n_envs"] >= 1 and hp["n_timesteps"] > 0 and "policy" in hp
        assert hp["env_kwargs"]["observation"] == "motor"
    assert parse_overrides(["learning_rate=1e-3", "env_kwargs.motor_history=48"]) == {
        "learning_rate": 1e-3,
        "env_kwargs": {"motor_history": 48},
    }


def test_training_errors_name_the_problem(tmp_path):
    with pytest.raises(ValueError, match="unknown algorithm 'a2c'"):
        train("drillgym/Torsional-v0", "a2c", tmp_path)
    with pytest.raises(ValueError, match="no entry for 'drillgym/Lateral-v0'"):
        train("drillgym/Lateral-v0", "sac", tmp_path)
    with pytest.raises(FileNotFoundError, match="nothere.yml"):
        train("drillgym/Torsional-v0", "sac", tmp_path, hyperparams=tmp_path / "nothere.yml")
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        train("drillgym/Torsional-v0", "sac", tmp_path / "fresh", resume=True, timesteps=10, progress=False)
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_overrides(["learning_rate"])


@pytest.mark.parametrize(
    "items",
    [["n_envs=2", "n_envs=4"], ["env_kwargs.motor_history=8", "env_kwargs.motor_history=16"]]
    + [["env_kwargs.motor_history=8", "env_kwargs={}"]],
    ids=["twice", "nested-twice", "beside-its-part"],
)
def test_an_override_given_twice_is_refused(items):
    """Two --set of one key: the first would be dropped without a word."""
    with pytest.raises(ValueError, match="given twice"):
        parse_overrides(items)


def run_cli(capsys, *args) -> tuple[int, str]:
    """``drillgym ARGS`` in this process (torch is imported once): exit code, stdout + stderr."""
    from drillgym.cli import main

    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out = capsys.readouterr()
    return exc.value.code or 0, out.out + out.err


def test_cli_train_writes_an_agent_for_evaluate(tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    monkeypatch.setattr(sys, "argv", ["drillgym", "train", "--seed", "4"])  # what config.yml records
    code, text = run_cli(
        capsys,
        "train",
        "--env",
        "drillgym/Torsional-v0",
        "--algo",
        "sac",
        "--obs",
        "motor",
        "--timesteps",
        "64",
        "--n-envs",
        "2",
        "--seed",
        "4",
        "--set",
        "learning_starts=16",
        "--set",
        "buffer_size=500",
        "--no-progress",
        "--no-tensorboard",
        "--out",
        str(out),
    )
    assert code == 0, text
    assert "trained 64 steps" in text
    cfg = yaml.safe_load((out / "config.yml").read_text())
    assert cfg["command"].startswith("drillgym train") and "--seed 4" in cfg["command"]
    ctrl = controllers.make(f"agent:{out / 'model.zip'}", config="coupled", omega_ref=4.0)
    ctrl.reset({"t": 0.0, "theta_u": 0.0})
    assert -5.0 <= ctrl.act({"t": 0.01, "theta_u": 0.01}) <= 5.0
    code, text = run_cli(capsys, "train", "--algo", "a2c", "--out", str(tmp_path / "x"))
    assert code == 2 and "--algo must be one of" in text and "'a2c'" in text


def test_residual_voltage_structure():
    from agents.residual import ResidualVoltage
    from drillgym.equilibria import equilibrium_voltage

    ref = np.array([2.0, 3.0, 6.0])
    u_eq = equilibrium_voltage("torsional", ref)
    plain = ResidualVoltage("torsional", 1.5)
    np.testing.assert_allclose(plain.voltage(np.zeros(3), ref), u_eq)  # a = 0: the baseline
    np.testing.assert_allclose(plain.voltage([1.0, -1.0, 9.0], ref), np.clip(u_eq + [1.5, -1.5, 1.5], -5, 5))
    sched = ResidualVoltage("torsional", 1.5, startup=(5.0, 3.0, 15.0))
    np.testing.assert_allclose(sched.feedforward(ref, 1.0), 5.0)  # kick above the fold
    np.testing.assert_allclose(sched.feedforward(ref, 10.5), 5.0 + (u_eq - 5.0) * 0.5)  # half-way down the ramp
    np.testing.assert_allclose(sched.feedforward(ref, np.array([18.0, 30.0, 99.0])), u_eq)
    with pytest.raises(ValueError, match="startup"):
        ResidualVoltage("torsional", 1.5, startup=(9.0, 3.0, 15.0))
    with pytest.raises(ValueError, match="scale"):
        ResidualVoltage("torsional", -1.0)


def test_ppo_resume_keeps_reward_normalisation(tmp_path):
    extra = {**FAST, "n_steps": 32, "batch_size": 64, "normalize_reward": True}
    train("drillgym/Torsional-v0", "ppo", tmp_path, timesteps=128, overrides=extra, progress=False, tensorboard=False)
    assert (tmp_path / "checkpoints" / "latest_vecnormalize.pkl").is_file()
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path,
        timesteps=256,
        overrides=extra,
        progress=False,
        tensorboard=False,
        resume=True,
    )
    assert res.timesteps == 256
    assert res.model.get_vec_normalize_env().ret_rms.count > 200  # 128 + 128 samples: statistics carried over


def test_cli_train_on_a_rig_with_effects(tmp_path, capsys):
    out = tmp_path / "eff"
    code, text = run_cli(
        capsys,
        "train",
        "--env",
        "drillgym/Torsional-v0",
        "--algo",
        "sac",
        "--obs",
        "motor",
        "--timesteps",
        "32",
        "--n-envs",
        "2",
        "--set",
        "learning_starts=16",
        "--set",
        "buffer_size=200",
        "--no-progress",
        "--no-tensorboard",
        "--out",
        str(out),
        "--add-effect",
        "input_delay",
        "--effect-param",
        "delay=0.04",
    )
    assert code == 0, text
    env_kwargs = yaml.safe_load((out / "config.yml").read_text())["hyperparams"]["env_kwargs"]
    assert env_kwargs["effects"] == ["input_delay"] and env_kwargs["effect_params"] == {"delay": 0.04}
    code, text = run_cli(capsys, "train", "--out", str(tmp_path / "y"), "--effect-param", "delay=0.04")
    assert code == 2 and "--add-effect" in text
