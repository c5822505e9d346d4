"""The mean of networks of one recipe as one wider network (agents/ensemble.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import agents
from agents.ensemble import average, average_networks
from agents.export import ExportedPolicy

ROBUST = agents.KEPT_POLICY.parents[1] / "torsional_motor_learned_robust" / "policy.npz"


def _member(seed: int, scale: float = 1.0) -> ExportedPolicy:
    """The kept robust network with its weights perturbed by ``seed`` (another member of its recipe)."""
    base = ExportedPolicy.load(ROBUST)
    rng = np.random.default_rng(seed)
    arrays = base.to_arrays()
    for key in [k for k in arrays if k[0] in "Wb"]:
        arrays[key] = arrays[key] * scale + 0.05 * rng.standard_normal(arrays[key].shape).astype(np.float32)
    meta = json.loads(json.dumps(base.meta))
    meta["config"]["seed"] = seed
    return ExportedPolicy.from_arrays(meta, arrays)


def test_the_averaged_network_acts_as_the_mean_of_its_members(tmp_path) -> None:
    """Every observation: the one network's action is the members' mean output, clipped once; it is written and
    read back as a plain policy.npz that names its members' seeds."""
    members = [_member(s) for s in (1, 2, 3)]
    net = average_networks(members)
    obs = np.random.default_rng(0).normal(size=(200, net.obs_dim)).astype(np.float32)

    def raw(m: ExportedPolicy) -> np.ndarray:  # the member's output before its clip
        x = obs
        if m.obs_norm is not None:
            mean, scale, clip = m.obs_norm
            x = np.clip((x - mean) * scale, -clip, clip)
        for (Wt, b), act in zip(m.layers, m.activations, strict=True):
            x = act(x @ Wt + b)
        return x

    expected = np.clip(np.mean([raw(m) for m in members], axis=0), -1.0, 1.0)
    np.testing.assert_allclose(net.act(obs), expected, atol=2e-6)
    assert not np.allclose(net.act(obs), members[0].act(obs), atol=1e-3)  # not just one member
    path = net.save(tmp_path / "mean.npz")
    back = agents.load_policy(str(path))
    np.testing.assert_array_equal(back.act(obs), net.act(obs))
    assert [m["seed"] for m in back.meta["ensemble"]] == [1, 2, 3]


def test_networks_of_another_recipe_are_refused(tmp_path) -> None:
    a = _member(1)
    meta = json.loads(json.dumps(a.meta))
    meta["config"]["hyperparams"]["distill"] = {"teacher": "observer"}
    other = ExportedPolicy.from_arrays(meta, a.to_arrays())
    with pytest.raises(ValueError, match="another training configuration"):
        average_networks([a, other])
    with pytest.raises(ValueError, match="at least two"):
        average_networks([a])
    with pytest.raises(FileNotFoundError):
        average([ROBUST, tmp_path / "missing.npz"], tmp_path / "x.npz")
    assert not (tmp_path / "x.npz").exists()
