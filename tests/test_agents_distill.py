"""Teacher -> student distillation (DAgger): a full-state teacher taught to a motor-side network."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import yaml

import drillgym  # noqa: F401
from agents.export import ExportedPolicy
from agents.train import train


def _teacher(path) -> None:
    """A linear 'full'-observation teacher whose action depends on the target: a = 0.1 omega_ref - 0.5."""
    meta = {"format": 1, "activations": ["identity"], "output": "clip", "obs_dim": 5,
            "config": {"env_id": "drillgym/Torsional-v0", "algo": "ppo",
                       "hyperparams": {"env_kwargs": {"observation": "full"}}}}
    np.savez(path, meta=np.array(json.dumps(meta)), action_low=np.float32([-1]), action_high=np.float32([1]),
             W0=np.float32([[0.0, 0.0, 0.0, 0.0, 0.1]]), b0=np.float32([-0.5]))


def test_student_on_the_motor_side_learns_the_teachers_actions(tmp_path) -> None:
    _teacher(tmp_path / "teacher.npz")
    res = train("drillgym/Torsional-v0", "ppo", tmp_path / "student", timesteps=0, seed=0, progress=False,
                tensorboard=False, teacher=tmp_path / "teacher.npz",
                overrides={"n_envs": 8, "env_kwargs": {"episode_duration": 1.0}},
                distill_kwargs={"iterations": 2, "steps": 60, "epochs": 60, "lr": 3e-3})
    assert res.timesteps == 0
    cfg = yaml.safe_load((tmp_path / "student" / "config.yml").read_text())
    assert cfg["teacher"]["policy"].endswith("teacher.npz") and cfg["hyperparams"]["env_kwargs"]["observation"] == "motor"
    student = ExportedPolicy.load(res.policy_path)
    assert student.obs_dim == 33  # the motor side only (the privileged critic's entries are not deployed)
    errors, spread = [], []
    for ref in (2.5, 4.0, 5.5, 7.0):  # the states the student visits (DAgger trained it on those)
        env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=ref, episode_duration=1.0)
        obs, _ = env.reset(seed=1)
        for _ in range(60):
            a = student.act(obs)
            errors.append(abs(float(a[0]) - (0.1 * ref - 0.5)))
            obs, *_ = env.step(a)
        spread.append(0.1 * ref - 0.5)
    assert np.median(errors) < 0.05 < np.ptp(spread) / 4  # follows the target dependence it was taught
