"""Agents: a training run that starts from a kept policy's weights (``drillgym train --init DIR``) on a model."""

import json

import numpy as np
import pytest
import yaml
from stable_baselines3.common.save_util import load_from_zip_file

import agents.finetune
import controllers
from agents.train import train

KEPT = "agents/policies/torsional_motor_ppo"  # a small kept PPO run (33-64-64-1) with its model.zip
FAST = {
    "privileged_critic": False,
    "n_envs": 2,
    "n_steps": 64,
    "batch_size": 64,
    "n_epochs": 2,
    "env_kwargs": {"episode_duration": 1.0},
}


@pytest.fixture
def model_file(tmp_path):
    path = tmp_path / "model.json"
    path.write_text(json.dumps({"params": {"Ts": 0.3}, "effects": [{"spec": "motor_lag", "values": {"tau_m": 0.04}}]}))
    return path


def _weights(state: dict) -> dict[str, np.ndarray]:
    return {k: v.detach().cpu().numpy().copy() for k, v in state.items()}


def test_a_run_starts_from_the_init_weights_and_trains_them_on_the_model(tmp_path, model_file, monkeypatch):
    started = {}
    real = agents.finetune.start_from

    def spy(model, init, venv=None):
        path = real(model, init, venv)
        started.update(_weights(model.policy.state_dict()))
        return path

    monkeypatch.setattr(agents.finetune, "start_from", spy)
    res = train(
        "drillgym/Torsional-v0", "ppo", tmp_path / "adapted", timesteps=256, seed=2, overrides=FAST,
        progress=False, tensorboard=False, model=model_file, init=KEPT,
    )  # fmt: skip
    _, params, _ = load_from_zip_file(f"{KEPT}/model.zip", device="cpu")
    init = _weights(params["policy"])
    assert started.keys() == init.keys()
    assert all(np.array_equal(started[k], init[k]) for k in init)  # the run started from the init policy
    after = _weights(res.model.policy.state_dict())
    assert any(not np.allclose(after[k], init[k]) for k in ("action_net.weight", "mlp_extractor.policy_net.0.weight"))
    cfg = yaml.safe_load((tmp_path / "adapted" / "config.yml").read_text())
    assert cfg["init"] == KEPT and cfg["hyperparams"]["env_kwargs"]["model"]["params"]["Ts"] == 0.3
    # the adapted policy runs as a controller, built with the model it was adapted to, the effects it does not
    # use named
    with pytest.warns(UserWarning, match=r"base parameters only; its effects \(motor_lag\) are not used"):
        ctrl = controllers.make(f"agent:{tmp_path / 'adapted'}", model=model_file, omega_ref=3.0)
    assert ctrl.params.Ts == 0.3 and ctrl.uses == ("theta_u",)


@pytest.mark.parametrize(
    "args,words",
    [
        (["--algo", "ppo", "--obs", "sensors"], ("--init", "observation space is Box(33,)", "Box(7,)")),
        (["--algo", "sac"], ("--init", "ActorCriticPolicy (ppo)", "--algo")),
        (["--algo", "ppo", "--set", "policy_kwargs.net_arch=[8]"], ("--init", "network layer")),
    ],
    ids=["observation", "algorithm", "network"],
)
def test_a_mismatched_init_is_refused_in_one_line(tmp_path, capsys, args, words):
    from drillgym.cli import main

    out = tmp_path / "run"
    base = ["train", "--init", KEPT, "--set", "privileged_critic=false", "--timesteps", "64", "--n-envs", "2"]
    with pytest.raises(SystemExit) as exc:
        main([*base, "--no-progress", "--no-tensorboard", "--out", str(out), *args])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and "\n" not in err, err
    assert all(w in err for w in words), err
    assert not out.exists()


def test_an_init_without_a_model_zip_is_refused(tmp_path):
    with pytest.raises(Exception, match="no model.zip"):
        agents.finetune.init_model_file("agents/policies/population_motor_distilled_mean")
    (tmp_path / "x.zip").write_text("not a zip")
    with pytest.raises(Exception, match="not an SB3 model"):
        agents.finetune.init_model_file(tmp_path / "x.zip")


def test_an_unreadable_init_is_refused_before_any_warning(tmp_path, capsys):
    """A zip that is not an SB3 model, given to a run too short to learn (which is warned about), is refused in
    one line with no warning before it: the warning is for a run that goes ahead."""
    import warnings
    import zipfile

    from drillgym.cli import main

    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("data", "not an SB3 model")
    out = tmp_path / "run"
    argv = ["train", "--init", str(bad), "--timesteps", "1", "--no-progress", "--no-tensorboard", "--out", str(out)]
    with warnings.catch_warnings(record=True) as seen, pytest.raises(SystemExit) as exc:
        warnings.simplefilter("always")
        main(argv)
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and "\n" not in err and "--init" in err, err
    assert [str(w.message) for w in seen] == []
    assert not out.exists()


def test_an_init_with_non_finite_weights_is_refused_before_out_is_written(tmp_path, capsys):
    """A model.zip whose network holds a NaN is refused in one line naming the layer; OUT is not created (the run
    would fail at its first step with a traceback, its directory written)."""
    import io
    import zipfile

    import torch

    from drillgym.cli import main

    bad = tmp_path / "init" / "model.zip"
    bad.parent.mkdir()
    with zipfile.ZipFile(f"{KEPT}/model.zip") as zin, zipfile.ZipFile(bad, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename == "policy.pth":
                state = torch.load(io.BytesIO(data), weights_only=True)
                key = next(k for k in state if k.endswith("weight"))
                state[key][0, 0] = float("nan")
                buf = io.BytesIO()
                torch.save(state, buf)
                data = buf.getvalue()
            zout.writestr(info, data)
    out = tmp_path / "run"
    base = ["train", "--init", str(bad.parent), "--set", "privileged_critic=false", "--algo", "ppo"]
    with pytest.raises(SystemExit) as exc:
        main([*base, "--timesteps", "64", "--n-envs", "2", "--no-progress", "--no-tensorboard", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and "\n" not in err and "non-finite" in err and key in err, err
    assert not out.exists()
