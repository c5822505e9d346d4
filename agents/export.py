"""Export of a trained SB3 policy to plain numpy weights (``.npz``) and the rig-side policy.

The deterministic policy of PPO, SAC and TD3 with an MLP is a chain of affine layers
and element-wise activations; :func:`export_policy` writes the weights
(``W0, b0, W1, b1, ...`` float32), the activations and everything the rig needs to
rebuild the observation and the voltage (``meta``: env id, algorithm, env options,
residual scale, frame stacking) into one ``.npz``.  :class:`ExportedPolicy` evaluates
it with numpy only (no torch, no SB3): a 33-64-64-1 MLP takes a few microseconds.

Output transform: SAC squashes the Gaussian mean with tanh; PPO clips the mean to the
action space (or squashes it with tanh under gSDE's ``squash_output``); TD3's actor ends with tanh
already (then clipping is the identity).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import InputError, InputTypeError, MissingFileError

__all__ = ["export_policy", "ExportedPolicy", "policy_file", "policy_layers", "ACTIVATIONS", "FORMAT_VERSION"]

FORMAT_VERSION = 1
ACTIVATIONS = {
    "relu": lambda x: np.maximum(x, 0.0, out=x),
    "tanh": lambda x: np.tanh(x, out=x),
    "elu": lambda x: np.where(x > 0, x, np.expm1(np.minimum(x, 0.0))),
    "identity": lambda x: x,
}


def _activation(name: str):
    """numpy function of an activation name ('relu', 'tanh', 'elu', 'identity', 'hardtanh:MIN:MAX')."""
    if name.startswith("hardtanh:"):
        lo, hi = (float(v) for v in name.split(":")[1:])
        return lambda x: np.clip(x, lo, hi, out=x)
    if name not in ACTIVATIONS:
        raise InputError(f"unknown activation {name!r} in exported policy")
    return ACTIVATIONS[name]


def _walk(module, layers: list, acts: list) -> None:
    import torch.nn as nn

    simple = {nn.ReLU: "relu", nn.Tanh: "tanh", nn.ELU: "elu"}
    if isinstance(module, nn.Sequential):
        for m in module:
            _walk(m, layers, acts)
    elif isinstance(module, nn.Linear):
        layers.append(
            (
                module.weight.detach().cpu().numpy().astype(np.float32),
                module.bias.detach().cpu().numpy().astype(np.float32),
            )
        )
        acts.append("identity")
    elif type(module) in simple or isinstance(module, nn.Hardtanh):
        if not acts or acts[-1] != "identity":
            raise InputError(f"activation {module} does not follow a linear layer; cannot export")
        acts[-1] = (
            f"hardtanh:{module.min_val}:{module.max_val}" if isinstance(module, nn.Hardtanh) else simple[type(module)]
        )
    elif isinstance(module, (nn.Flatten, nn.Identity)):
        pass
    else:
        raise InputError(f"cannot export layer {type(module).__name__} to numpy (MLP policies only)")


def policy_layers(model) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[str], str]:
    """(layers [(W, b)], activation after each layer, output transform 'tanh'|'clip') of the
    deterministic actor of an SB3 PPO/SAC/TD3 model with an MLP policy."""
    from stable_baselines3 import PPO, SAC, TD3

    layers: list = []
    acts: list = []
    if isinstance(model, SAC):
        _walk(model.policy.actor.latent_pi, layers, acts)
        _walk(model.policy.actor.mu, layers, acts)
        output = "tanh"
    elif isinstance(model, TD3):
        _walk(model.policy.actor.mu, layers, acts)
        output = "clip"
    elif isinstance(model, PPO):
        _walk(model.policy.mlp_extractor.policy_net, layers, acts)
        _walk(model.policy.action_net, layers, acts)
        output = "tanh" if getattr(model.policy, "squash_output", False) else "clip"  # gSDE with squash_output
    else:
        raise InputError(f"cannot export a {type(model).__name__} policy to numpy (PPO, SAC, TD3 only)")
    k = actor_dim(model)
    if k < layers[0][0].shape[1]:  # privileged critic: the actor's zero-masked inputs are dropped
        layers[0] = (np.ascontiguousarray(layers[0][0][:, :k]), layers[0][1])
    return layers, acts, output


def actor_dim(model) -> int:
    """Observation entries the deployed actor reads (fewer than the env's with a privileged critic,
    :mod:`agents.privileged`)."""
    return int(getattr(model.policy, "actor_dim", model.observation_space.shape[0]))


def obs_normalization(model) -> dict[str, np.ndarray] | None:
    """Frozen observation statistics of the model's ``VecNormalize`` (None without obs normalisation):
    ``obs_mean``, ``obs_scale`` (1 / sqrt(var + eps)) and ``obs_clip`` (normalised values clipped to
    +/- it), float32."""
    venv = model.get_vec_normalize_env()
    if venv is None or not venv.norm_obs:
        return None
    rms, k = venv.obs_rms, actor_dim(model)
    return {
        "obs_mean": rms.mean[:k].astype(np.float32),
        "obs_scale": (1.0 / np.sqrt(rms.var[:k] + venv.epsilon)).astype(np.float32),
        "obs_clip": np.float32(venv.clip_obs),
    }


def export_policy(model, path: str | Path, config: dict[str, Any]) -> Path:
    """Write the deterministic policy of a model as a numpy file.

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        A trained SB3 model with an MLP policy.
    path : str or path
        Output ``.npz`` file.
    config : dict
        The run's configuration (see :mod:`agents.train`), stored in the file's metadata.

    Returns
    -------
    Path
        The path written: weights, activations, action bounds, and the frozen observation
        normalisation when the model trained with one.
    """
    layers, acts, output = policy_layers(model)
    low, high = model.action_space.low.astype(np.float32), model.action_space.high.astype(np.float32)
    meta = {
        "format": FORMAT_VERSION,
        "activations": acts,
        "output": output,
        "obs_dim": actor_dim(model),
        "config": config,
    }
    arrays = {f"W{i}": W for i, (W, _) in enumerate(layers)} | {f"b{i}": b for i, (_, b) in enumerate(layers)}
    arrays |= obs_normalization(model) or {}
    return _write(path, meta, {"action_low": low, "action_high": high} | arrays)


def _write(path: str | Path, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> Path:
    """One network's ``.npz``: its metadata as strict JSON (no NaN literal) beside its arrays."""
    path = Path(path)
    np.savez(path, meta=np.array(json.dumps(meta, default=_jsonable, allow_nan=False)), **arrays)
    return path


@contextmanager
def policy_file(path: str | Path, kind: str) -> Iterator[tuple[dict[str, Any], Any]]:
    """``(meta, arrays)`` of the policy file at ``path`` (an open ``.npz``), for reading inside the block; a
    missing file, or one that is not a ``kind`` (a missing array, bad metadata), is named in the error."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{kind} {path} not found")
    try:
        with np.load(path, allow_pickle=False) as z:
            yield json.loads(str(z["meta"])), z
    except (KeyError, ValueError, OSError) as exc:
        article = "an" if kind[0] in "aeiou" else "a"
        raise InputError(f"{path} is not {article} {kind}: {exc}") from exc


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (tuple, set)):
        return list(o)
    raise InputTypeError(f"cannot store {type(o).__name__} in the policy metadata")


def _check_network(layers, low, high, meta: dict[str, Any], obs_norm) -> None:
    """Refuse a network that cannot act: non-finite weights, bounds or normalisation, or layers whose shapes
    do not chain from the observation (``meta['obs_dim']``) to the action (the bounds' size)."""
    try:
        obs_dim = int(meta["obs_dim"])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"bad exported policy: obs_dim {meta.get('obs_dim')!r} is not a size") from None
    if obs_dim < 1:
        raise InputError(f"bad exported policy: obs_dim must be >= 1, got {obs_dim}")
    named = [(f"W{i}", W) for i, (W, _) in enumerate(layers)] + [(f"b{i}", b) for i, (_, b) in enumerate(layers)]
    named += [("action_low", low), ("action_high", high)]
    if obs_norm is not None:
        named += [("obs_mean", obs_norm[0]), ("obs_scale", obs_norm[1]), ("obs_clip", obs_norm[2])]
    for name, a in named:
        a = np.asarray(a)
        if a.dtype.kind not in "fiu":
            raise InputError(f"bad exported policy: {name} holds {a.dtype} values, not numbers")
        if not np.isfinite(a).all():
            bad = int(np.size(a) - np.isfinite(a).sum())
            raise InputError(f"bad exported policy: {name} holds {bad} non-finite value(s) (NaN or inf)")
    width = obs_dim
    for i, (W, b) in enumerate(layers):
        W, b = np.asarray(W), np.asarray(b)
        if W.ndim != 2 or W.shape[1] != width or b.shape != (W.shape[0],):
            raise InputError(
                f"bad exported policy: layer {i} has weights {W.shape} and bias {b.shape}, "
                f"not (n, {width}) and (n,) (the layers do not chain from the {obs_dim} observation entries)"
            )
        width = W.shape[0]
    low, high = np.asarray(low), np.asarray(high)
    if low.shape != (width,) or high.shape != (width,) or not (low < high).all():
        raise InputError(
            f"bad exported policy: action bounds {low.shape}, {high.shape} do not fit its {width} output(s) "
            "(or low is not below high)"
        )
    if obs_norm is not None and (
        np.shape(obs_norm[0]) != (obs_dim,) or np.shape(obs_norm[1]) != (obs_dim,) or not float(obs_norm[2]) > 0
    ):
        raise InputError(f"bad exported policy: its observation normalisation does not fit {obs_dim} entries")


class ExportedPolicy:
    """A policy exported by :func:`export_policy`, evaluated with numpy (float32).

    Observations are first standardised with the training's frozen statistics when it normalised them
    (``obs_norm``).  Usually built by :meth:`load` or :func:`agents.load_policy`.

    Parameters
    ----------
    layers : list of tuple of ndarray
        (W, b) of each layer, W of shape (out, in).
    activations : list of str
        Activation after each layer.
    output : str
        ``"tanh"`` or ``"clip"``: how the last layer maps into the action bounds.
    action_low, action_high : ndarray
        Bounds of the training env's action space.
    meta : dict
        The file's metadata (``obs_dim``, the run's ``config``).
    obs_norm : tuple, optional
        (mean, 1/std, clip) of the training's observation normalisation.
    """

    def __init__(
        self,
        layers: list[tuple[np.ndarray, np.ndarray]],
        activations: list[str],
        output: str,
        action_low: np.ndarray,
        action_high: np.ndarray,
        meta: dict[str, Any],
        obs_norm: tuple[np.ndarray, np.ndarray, float] | None = None,
    ) -> None:
        if len(activations) != len(layers) or output not in ("tanh", "clip"):
            raise InputError(f"bad exported policy: activations {activations}, output {output!r}")
        _check_network(layers, action_low, action_high, meta, obs_norm)
        self.layers = [(np.ascontiguousarray(W.T), b) for W, b in layers]  # x @ W.T + b
        self.activations = [_activation(a) for a in activations]
        self.output = output
        self.low, self.high = action_low, action_high
        self.meta = meta
        self.obs_dim = int(meta["obs_dim"])
        self.obs_norm = obs_norm  # (mean, 1/std, clip) of the training's VecNormalize, or None

    @classmethod
    def load(cls, path: str | Path) -> ExportedPolicy:
        """The policy in a ``policy.npz`` of one network (:func:`agents.load_policy` also reads switched sets)."""
        with policy_file(path, "exported drillgym policy") as (meta, z):
            if "members" in meta:
                raise InputError("it is a target-switched policy of several networks; load it with agents.load_policy")
            return cls.from_arrays(meta, z)

    @classmethod
    def from_arrays(cls, meta: dict[str, Any], arrays: Any, prefix: str = "") -> ExportedPolicy:
        """The policy of ``meta`` whose weights are ``arrays[prefix + 'W0']``, ... (an open ``.npz`` or a dict)."""
        files = set(arrays.files if hasattr(arrays, "files") else arrays)
        n = len(meta["activations"])
        layers = [(arrays[f"{prefix}W{i}"], arrays[f"{prefix}b{i}"]) for i in range(n)]
        norm = (
            (arrays[f"{prefix}obs_mean"], arrays[f"{prefix}obs_scale"], float(arrays[f"{prefix}obs_clip"]))
            if f"{prefix}obs_mean" in files
            else None
        )
        return cls(
            layers,
            meta["activations"],
            meta["output"],
            arrays[f"{prefix}action_low"],
            arrays[f"{prefix}action_high"],
            meta,
            norm,
        )

    def to_arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The arrays :meth:`from_arrays` reads back (weights as exported, action bounds, normalisation)."""
        out = {f"{prefix}W{i}": np.ascontiguousarray(Wt.T) for i, (Wt, _) in enumerate(self.layers)}
        out |= {f"{prefix}b{i}": b for i, (_, b) in enumerate(self.layers)}
        out |= {f"{prefix}action_low": self.low, f"{prefix}action_high": self.high}
        if self.obs_norm is not None:
            mean, scale, clip = self.obs_norm
            out |= {f"{prefix}obs_mean": mean, f"{prefix}obs_scale": scale, f"{prefix}obs_clip": np.float32(clip)}
        return out

    def save(self, path: str | Path) -> Path:
        """Write the network to ``path`` (.npz), as :func:`export_policy` does: :meth:`load` reads it back."""
        return _write(path, self.meta, self.to_arrays())

    @property
    def config(self) -> dict[str, Any]:
        """The training run's configuration (env id, algo, seed, hyperparameters)."""
        return self.meta["config"]

    @property
    def control_dt(self) -> float:
        """Control period (s) the policy was trained at (the env's ``control_dt``, 10 ms by default)."""
        return float(self.config["hyperparams"].get("env_kwargs", {}).get("control_dt", 0.01))

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The deterministic action of each observation.

        Parameters
        ----------
        obs : ndarray
            Observations (n, obs_dim) or one (obs_dim,).

        Returns
        -------
        ndarray
            Actions (n, act_dim) or (act_dim,), in the training env's action space ([-1, 1]).
        """
        x = np.asarray(obs, dtype=np.float32)
        single = x.ndim == 1
        x = np.atleast_2d(x)
        if x.shape[1] != self.obs_dim:
            raise InputError(f"observation must have {self.obs_dim} entries, got {x.shape[1]}")
        if self.obs_norm is not None:
            mean, scale, clip = self.obs_norm
            x = np.clip((x - mean) * scale, -clip, clip)
        for (Wt, b), f in zip(self.layers, self.activations):
            x = f(x @ Wt + b)
        x = np.tanh(x) if self.output == "tanh" else x
        x = np.clip(x, self.low, self.high)
        return x[0] if single else x

    __call__ = act
