"""Training on an identified task: each rig's observer base is built on the identified model of the plant it runs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from agents.batch import episode_batch
from agents.envs import ObserverResidualVecEnv, make_training_env
from agents.plantwise_residual import PlantwiseObserverResidual
from controllers.evaluation.identify import IdentifiedPlant, save_identified
from drillgym import Model, RigParams
from drillgym.errors import InputError

TASK = "drillgym/Population-Motor-Identified-v0"


def _folder(tmp_path, kms):
    """Identifications of training plants 0.. with the given motor constants (told apart by them)."""
    found = {
        k: IdentifiedPlant(Model(replace(RigParams(), km=km), ("motor_lag",), {"tau_m": 0.03}), ["motor_lag"], 1.0)
        for k, km in enumerate(kms)
    }
    return str(save_identified(found, tmp_path / "train"))


def _wrapper(venv):
    while not isinstance(venv, ObserverResidualVecEnv):
        venv = venv.venv
    return venv


def test_each_rig_runs_a_listed_plant_on_the_base_built_on_its_model(tmp_path):
    kms = (4.0, 4.6)
    venv = make_training_env(
        TASK, 6, seed=3, residual=0.5, base="observer", observer={},
        identified={"plants": 2, "folder": _folder(tmp_path, kms)}, monitor=False,
    )  # fmt: skip
    venv.reset()
    base, batch = _wrapper(venv).base, episode_batch(venv)
    assert isinstance(base, PlantwiseObserverResidual)
    plants = batch.plant_index.copy()
    assert set(plants) <= {0, 1} and len(set(plants)) == 2  # only the identified plants, both drawn here
    for i, k in enumerate(plants):
        assert base._rigs[i].params.km == kms[k]  # the rig's base: its plant's identified model
    u_base = np.concatenate([r.u_base for r in base._rigs])
    assert np.array_equal(base.voltage(np.zeros(6)), np.clip(u_base, -5.0, 5.0))  # a = 0: each rig's observer
    for _ in range(50):
        obs, *_ = venv.step(np.zeros((6, 1), dtype=np.float32))
    assert obs.shape == (6, base.dim) and np.all(np.isfinite(obs))


def test_identified_training_refuses_what_does_not_fit(tmp_path):
    with pytest.raises(InputError, match="identified task"):
        make_training_env(
            "drillgym/Population-Motor-v0", 2, residual=0.5, base="observer", identified={"plants": 1}, monitor=False
        )
    with pytest.raises(InputError, match="needs base 'observer'"):
        make_training_env(TASK, 2, identified={"plants": 1, "folder": _folder(tmp_path, (4.0,))}, monitor=False)
    with pytest.raises(InputError, match="unknown key 'plant'"):
        make_training_env(TASK, 2, residual=0.5, base="observer", identified={"plant": 1}, monitor=False)
