"""Residual on the two-encoder LQG built on each training plant's identified model: with a zero residual each rig's
base is ``lqg-2enc`` on its own plant's model, to the bit; what does not fit is refused in one line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import controllers
from agents.envs import ResidualBaseVecEnv, make_training_env
from agents.plantwise_residual import PlantwiseResidual
from controllers.evaluation.identify import IdentifiedPlant, save_identified
from drillgym import Model, RigParams
from drillgym.errors import InputError

TASK = "drillgym/Population-TwoEncoder-Identified-v0"
HP = "agents/hyperparams/ppo_lqg2enc_identified.yml"


def _models(kms):
    """Identified models told apart by their motor constants (N m/V).  Without effects: a model with effects
    compiles its composition's kernels (about 20 s, once per process); the base runs the controller's own
    ``act`` and ``applied`` either way."""
    return [Model(replace(RigParams(), km=km)) for km in kms]


def _readings(k: int) -> dict[str, np.ndarray]:
    """Encoder angles (rad) of three rigs at period k: motors speeding up, the lower discs winding behind."""
    tu = 0.002 * k**1.4 * np.array([1.0, 1.0, 1.3])
    return {"theta_u": tu, "theta_l": tu - 0.3 * (1.0 - np.exp(-k / 40.0)) + np.array([0.1, 0.1, -0.2])}


def test_each_rig_base_is_lqg2enc_on_its_plants_model():
    """Rigs 0 and 1 share a target but run different plants: each gives, for a = 0, the voltage of
    ``controllers.make("lqg-2enc", model=its plant's model)`` fed the same angles, to the bit, and the two differ;
    with a residual applied, the base's filter predicts with the applied voltage as the controller's ``applied``."""
    models, plants, targets = _models((4.0, 4.6)), np.array([1, 0, 1]), np.array([2.0, 2.0, 5.0])
    base = PlantwiseResidual("lqg-2enc", "torsional", 0.5, models, dt=0.01)
    base.start(3)
    first = _readings(0)
    base.reset(np.arange(3), omega_ref=targets, plants=plants, **first)
    refs = []
    for i, p in enumerate(plants):
        c = controllers.make("lqg-2enc", omega_ref=targets[i], dt=0.01, model=models[p])
        c.reset({k: v[i] for k, v in first.items()})
        refs.append(c)
    apart = 0.0
    for k in range(300):
        m = _readings(k)
        base.correct(**m)
        base.base()
        a = np.zeros(3) if k < 150 else np.array([0.4, -0.2, 0.1])  # then a residual: the prediction follows it
        u = base.voltage(a)
        for i, c in enumerate(refs):
            u_ref = c.act({key: v[i] for key, v in m.items()})
            assert u[i] == np.clip(u_ref + 0.5 * a[i], -5.0, 5.0), f"period {k}, rig {i}"
            c.applied(u[i])
        base.predict(u)
        apart = max(apart, abs(u[0] - u[1]))
    assert apart > 0.01, apart  # the plant's model changes the base
    assert base.features().shape == (3, base.dim) and np.all(np.isfinite(base.features()))


def _folder(tmp_path, kms) -> str:
    found = {k: IdentifiedPlant(m, [], 1.0) for k, m in enumerate(_models(kms))}
    return str(save_identified(found, tmp_path / "train"))


def test_training_env_runs_each_listed_plant_on_its_lqg2enc(tmp_path):
    kms = (4.0, 4.6)
    venv = make_training_env(
        TASK, 4, seed=3, residual=0.5, base="lqg-2enc",
        identified={"plants": 2, "folder": _folder(tmp_path, kms)}, monitor=False,
    )  # fmt: skip
    obs = venv.reset()
    w = venv
    while not isinstance(w, ResidualBaseVecEnv):
        w = w.venv
    from agents.batch import episode_batch

    plants = episode_batch(venv).plant_index
    assert w.uses == ("theta_u", "theta_l") and set(plants) <= {0, 1}
    for i, k in enumerate(plants):
        assert w.base._rigs[i].params.km == kms[k]  # the rig's base: its plant's identified model
    for _ in range(30):
        obs, *_ = venv.step(np.zeros((4, 1), dtype=np.float32))
    assert obs.shape == (4, w.base.dim) and np.all(np.isfinite(obs))
    assert np.all(np.abs(w._theta[:, 0]) > 0.01)  # the motors turned, the unwrapped angles follow them


@pytest.mark.parametrize(
    ("task", "kw", "says"),
    [
        ("drillgym/Population-Motor-Identified-v0", {}, "'sensors' observation"),
        (TASK, {"observer": {"law_bandwidth": 2.0}}, "observer settings apply to base 'observer'"),
        (TASK, {"residual": None}, "needs a residual scale"),
        (TASK, {"base": "lqg"}, "base must be 'observer' or 'lqg-2enc'"),
        (TASK, {"identified": {"plants": 1, "folders": "x"}}, "unknown key 'folders'"),
    ],
)
def test_what_does_not_fit_is_refused_in_one_line(task, kw, says):
    args = {"residual": 0.5, "base": "lqg-2enc", **kw}
    with pytest.raises(InputError, match=says) as err:
        make_training_env(task, 2, monitor=False, **args)
    assert "\n" not in str(err.value)


def test_the_trained_policy_runs_on_lqg2enc_built_on_the_model_it_is_given(tmp_path):
    """A short run of the recipe writes a policy; ``controllers.make("agent:DIR", model=...)`` reads both encoders
    and, fed the angles of a rig, applies the voltage the training wrapper with that model's base applies."""
    from agents.train import train

    models = _models((4.0, 4.6))
    fast = {
        "n_envs": 2,
        "n_steps": 64,
        "batch_size": 64,
        "identified": {"plants": 2, "folder": _folder(tmp_path, (4.0, 4.6))},
    }
    res = train(
        TASK, "ppo", tmp_path / "run", timesteps=128, seed=0, hyperparams=HP,
        overrides=fast, progress=False, tensorboard=False, eval_every=0,
    )  # fmt: skip
    ctrl = controllers.make(f"agent:{res.policy_path}", omega_ref=np.array([1.0, 4.0]), model=models[1])
    assert ctrl.uses == ("theta_u", "theta_l")
    twin = PlantwiseResidual("lqg-2enc", "torsional", 0.5, models, dt=0.01)
    twin.start(2)
    first = _readings(0)
    ctrl.reset({k: v[:2] for k, v in first.items()})
    twin.reset(
        np.arange(2), omega_ref=np.array([1.0, 4.0]), plants=np.array([1, 1]), **{k: v[:2] for k, v in first.items()}
    )
    for k in range(100):
        m = {key: v[:2] for key, v in _readings(k).items()}
        u = ctrl.act(m)
        twin.correct(**m)
        twin.base()
        u_twin = twin.voltage(ctrl.policy.act(twin.features())[:, 0])
        twin.predict(u_twin)
        np.testing.assert_allclose(u, u_twin, atol=1e-6, err_msg=f"period {k}")
