"""A training run that starts from a kept policy's weights (``drillgym train --init DIR``).

What it is for: a policy adapted to the identified model of the rig before it runs there.  ``drillgym train
--model model.json --init runs/kept`` trains on the rig of the model (its base parameters and effects) from
the weights of ``runs/kept`` rather than from a fresh network: a few hundred thousand steps on the one rig
instead of a training from scratch.

    >>> from agents.train import train
    >>> res = train("drillgym/Torsional-v0", "ppo", "runs/adapted", model="model.json", init="runs/kept",
    ...             timesteps=200_000)

The init policy is a run directory of ``drillgym train`` (its ``model.zip``, the SB3 model) or that
``model.zip``: an exported ``policy.npz`` holds the actor only, with no critic to train on.  Its algorithm,
observation and action spaces and network layers must be this run's (the same observation mode and
options, the same ``policy_kwargs``); anything else is refused in one line naming the mismatch.  Every
weight of the policy (actor, critic, PPO's log standard deviation) is copied; the optimiser starts fresh
with the run's learning rate, and the run's observation normalisation (``normalize_obs``) starts from the
init run's statistics when it saved them (``checkpoints/latest_vecnormalize.pkl``).
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

from drillgym.errors import InputError, MissingFileError

__all__ = ["init_model_file", "start_from"]


def init_model_file(init: str | Path) -> Path:
    """The SB3 ``model.zip`` of an init policy.

    Parameters
    ----------
    init : str or path
        A run directory of ``drillgym train`` or its ``model.zip``.

    Returns
    -------
    Path
        The ``model.zip``.

    Raises
    ------
    MissingFileError
        No such path, or a directory without ``model.zip``.
    InputError
        A file that is not a zip archive.
    """
    p = Path(init)
    if p.is_dir():
        z = p / "model.zip"
        if not z.is_file():
            raise MissingFileError(
                f"init {p}: no model.zip in it (a run directory of `drillgym train`; an exported policy.npz alone "
                "has no critic to train on)"
            )
        return z
    if not p.exists():
        raise MissingFileError(f"init {p}: not found (a run directory of `drillgym train` or its model.zip)")
    if not zipfile.is_zipfile(p):
        raise InputError(f"init {p}: not an SB3 model (model.zip) nor a run directory holding one")
    return p


def _algo_of(z: Path) -> str:
    """`` (ALGO)`` as the init run's ``config.yml`` names it, or empty."""
    import yaml

    try:
        algo = yaml.safe_load((z.parent / "config.yml").read_text(encoding="utf-8")).get("algo")
    except (OSError, ValueError, AttributeError, yaml.YAMLError):
        return ""
    return f" ({algo})" if isinstance(algo, str) else ""


def _space(space: Any) -> str:
    shape = getattr(space, "shape", None)
    return f"{type(space).__name__}{tuple(shape) if shape is not None else ''}"


def start_from(model: Any, init: str | Path, venv: Any = None) -> Path:
    """Copy the policy weights of an init run into a freshly built model (before its first step).

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The run's model, as built from its hyperparameters.
    init : str or path
        The init policy (:func:`init_model_file`).
    venv : VecEnv, optional
        The run's training env: when it normalises observations and the init run saved its statistics
        beside its checkpoint, they are loaded into it.

    Returns
    -------
    Path
        The init ``model.zip``.

    Raises
    ------
    InputError
        An unreadable model, one with non-finite weights, or one of another algorithm, observation space, action
        space or network (naming the first difference).
    """
    from stable_baselines3.common.save_util import load_from_zip_file

    z = init_model_file(init)
    try:
        data, params, _ = load_from_zip_file(z, device="cpu", print_system_info=False)
    except Exception as exc:  # noqa: BLE001 - anything SB3 cannot read is not a model it wrote
        why = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise InputError(f"init {z}: not a readable SB3 model ({why})") from None
    if not isinstance(data, dict) or not isinstance(params, dict) or "policy" not in params:
        raise InputError(f"init {z}: not a readable SB3 model (no policy weights)")
    for key, value in params["policy"].items():
        if hasattr(value, "isfinite") and not bool(value.isfinite().all()):
            raise InputError(f"init {z}: its network layer {key} holds non-finite weights (NaN or infinite)")
    theirs = getattr(data.get("policy_class"), "__name__", data.get("policy_class"))
    if theirs is not None and theirs != type(model.policy).__name__:
        raise InputError(
            f"init {z}: its policy is {theirs}{_algo_of(z)}, this run's {type(model.policy).__name__} "
            f"({type(model).__name__.lower()}): train with the init run's --algo and hyperparameters (its config.yml)"
        )
    for what, mine in (("observation", model.observation_space), ("action", model.action_space)):
        other = data.get(f"{what}_space")
        if other is None or other != mine:
            raise InputError(
                f"init {z}: its {what} space is {_space(other)}, this run's is {_space(mine)}"
                + (" or its bounds differ" if _space(other) == _space(mine) else "")
                + " (train with the init run's observation mode and env options)"
            )
    state, weights = model.policy.state_dict(), params["policy"]
    for key, value in state.items():
        if key not in weights or tuple(weights[key].shape) != tuple(value.shape):
            had = "no such layer" if key not in weights else f"shape {tuple(weights[key].shape)}"
            raise InputError(
                f"init {z}: network layer {key} is {tuple(value.shape)} in this run, {had} in the init policy "
                "(train with the init run's policy_kwargs)"
            )
    extra = sorted(set(weights) - set(state))
    if extra:
        raise InputError(f"init {z}: its network has layer {extra[0]}, this run's has not (another policy_kwargs)")
    model.policy.load_state_dict(weights)
    stats = z.parent / "checkpoints" / "latest_vecnormalize.pkl"
    if venv is not None and getattr(venv, "norm_obs", False) and stats.is_file():
        from stable_baselines3.common.vec_env import VecNormalize

        saved = VecNormalize.load(str(stats), venv.venv)
        venv.obs_rms = saved.obs_rms
    return z
