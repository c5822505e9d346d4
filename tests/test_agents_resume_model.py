"""Agents: a resumed run keeps the model it was trained on (``drillgym train --model FILE ... --resume``)."""

import shutil

import pytest
import yaml

from agents.train import train
from drillgym import Model, RigParams
from drillgym.errors import InputError

FAST = {
    "privileged_critic": False,
    "n_envs": 2,
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 1,
    "env_kwargs": {"episode_duration": 1.0},
}
KW = dict(overrides=FAST, progress=False, tensorboard=False, checkpoint_every=128)


def test_a_run_trained_on_a_model_resumes_only_on_that_model(tmp_path):
    model = Model(RigParams().replace(Ts=0.3), ("motor_lag",), {"tau_m": 0.04}).save(tmp_path / "m" / "model.json")
    run = tmp_path / "run"
    train("drillgym/Torsional-v0", "ppo", run, timesteps=128, seed=0, model=model, **KW)
    before = (run / "config.yml").read_text()
    with pytest.raises(InputError, match=r"trained on the model motor_lag .*give the same model"):
        train("drillgym/Torsional-v0", "ppo", run, timesteps=256, seed=0, resume=True, **KW)
    other = Model(RigParams().replace(Ts=0.3), ("motor_lag",), {"tau_m": 0.05})
    with pytest.raises(InputError, match="trained on another model"):
        train("drillgym/Torsional-v0", "ppo", run, timesteps=256, seed=0, resume=True, model=other, **KW)
    assert (run / "config.yml").read_text() == before  # a refused resume leaves the run as it was
    shutil.copytree(tmp_path / "m", tmp_path / "copy")  # the same model from a copied folder
    res = train(
        "drillgym/Torsional-v0", "ppo", run, timesteps=256, seed=0, resume=True, model=tmp_path / "copy" / "model.json",
        **KW,
    )  # fmt: skip
    assert res.model.num_timesteps >= 256
    cfg = yaml.safe_load((run / "config.yml").read_text())
    assert cfg["hyperparams"]["env_kwargs"]["model"]["label"] == "motor_lag"


def test_a_run_trained_without_a_model_does_not_resume_on_one(tmp_path):
    run = tmp_path / "run"
    train("drillgym/Torsional-v0", "ppo", run, timesteps=128, seed=0, **KW)
    with pytest.raises(InputError, match="trained without a model"):
        train(
            "drillgym/Torsional-v0",
            "ppo",
            run,
            timesteps=256,
            seed=0,
            resume=True,
            model=Model(effects=("motor_lag",)),
            **KW,
        )
