"""Hyperparameters in the rl-zoo3 layout: one YAML file per algorithm, one entry per env id.

``agents/hyperparams/<algo>.yml``: the env id's entry holds only what rl-zoo3 reads (its own keys and
the SB3 algorithm's keywords), so ``python -m rl_zoo3.train --algo ppo --env drillgym/Torsional-v0
--gym-packages drillgym -conf agents/hyperparams/ppo.yml`` trains it unchanged::

    drillgym/Torsional-v0:
      n_envs: 32                 # rl-zoo3: rigs (drillgym: of the batched DrillVectorEnv)
      n_timesteps: !!float 1e6   # rl-zoo3: default training length
      policy: MlpPolicy
      normalize: "{'norm_obs': True, 'norm_reward': True}"   # rl-zoo3: VecNormalize keywords (or true/false)
      frame_stack: 1             # rl-zoo3: VecFrameStack depth (the 'motor' mode already holds a history)
      noise_type: normal         # rl-zoo3: action noise of TD3/SAC (with noise_std)
      learning_rate: !!float 3e-4
      ...                        # any keyword of the SB3 algorithm
      policy_kwargs: {net_arch: [64, 64]}
      env_kwargs: {observation: motor, randomize: 0.2, ...}   # drillgym EnvOptions (gymnasium.make keywords)

drillgym's own policy structures (read by drillgym only, in a separate top-level section ``drillgym``
keyed by env id; rl-zoo3 ignores other top-level keys)::

    drillgym:
      drillgym/Torsional-v0:
        residual: 2.0              # action = correction (V) on the feedforward voltage; absent = plain voltage
        startup: [5.0, 3.0, 15.0]  # feedforward start-up schedule (kick V, hold s, ramp s), see agents/residual.py
        base: observer             # the residual corrects the observer controller (agents/observer_residual.py)
        observer: {}               # keywords of that controller (controllers.observer.ObserverController)
        identified: {plants: 32, folder: runs/identified/train}   # identified tasks: each rig's base on its
                                   # training plant's identified model (agents/plantwise_residual.py; training only)
        privileged_critic: true    # PPO's critic also sees omega_l, stuck, SSI (agents/privileged.py; training only)
        motor_integral: true       # the motor-angle tracking integral appended to the observation (agents/integral.py)
        distill: {teacher: flatness, iterations: 16, population: default}   # DAgger before the RL steps
                                   # (agents/distill.py keywords; training only)

The merged entry (:func:`load_hyperparams`) holds both; ``normalize`` becomes ``normalize_obs`` /
``normalize_reward`` (the obs statistics are exported with the policy, :mod:`agents.export`).

As in rl-zoo3, ``policy_kwargs`` may also be a string (``"dict(net_arch=[64, 64])"``);
it is parsed with :func:`ast.literal_eval`-like rules (no code is executed).
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import yaml

from drillgym.errors import InputError, MissingFileError
from drillgym.io import describe_parse_error
from drillgym.io.structured import load_yaml

__all__ = [
    "HYPERPARAMS_DIR",
    "load_hyperparams",
    "parse_overrides",
    "apply_overrides",
    "DRILLGYM_KEYS",
    "ZOO_KEYS",
    "STRUCTURE_SECTION",
    "STRUCTURE_KEYS",
    "algorithm_kwargs",
]

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
#: keys of an rl-zoo3 entry that are not keywords of the SB3 algorithm (rl-zoo3 pops them itself)
ZOO_KEYS = (
    "n_envs",
    "n_timesteps",
    "policy",
    "env_kwargs",
    "normalize",
    "frame_stack",
    "env_wrapper",
    "callback",
    "noise_type",
    "noise_std",
    "vec_env_wrapper",
    "eval_env_kwargs",
    "normalize_kwargs",
)
#: top-level section of a hyperparameter file with drillgym's policy structures (per env id)
STRUCTURE_SECTION = "drillgym"
#: drillgym's own keys (the structure section, and the merged entry's normalisation flags)
STRUCTURE_KEYS = (
    "hyperparams_entry",
    "residual",
    "startup",
    "base",
    "observer",
    "normalize_reward",
    "normalize_obs",
    "privileged_critic",
    "distill",
    "motor_integral",
    "command_schedule",
    "population",
    "nominal_fraction",
    "nominal_below",
    "identified",
)
#: every key of a merged entry that is not a keyword of the SB3 algorithm
DRILLGYM_KEYS = ZOO_KEYS + STRUCTURE_KEYS


def algorithm_kwargs(entry: dict[str, Any]) -> dict[str, Any]:
    """The SB3 algorithm keywords of a (raw or merged) entry: everything but :data:`DRILLGYM_KEYS`."""
    return {k: v for k, v in entry.items() if k not in DRILLGYM_KEYS}


def _normalize_flags(v: Any) -> tuple[bool, bool]:
    """(norm_obs, norm_reward) of rl-zoo3's ``normalize`` value: bool, dict or a dict's string."""
    if isinstance(v, str):
        v = _parse_policy_kwargs(v)
    if isinstance(v, dict):
        return bool(v.get("norm_obs", True)), bool(v.get("norm_reward", True))
    return bool(v), bool(v)


def _parse_policy_kwargs(v: Any) -> dict:
    if isinstance(v, dict):
        return dict(v)
    if isinstance(v, str):
        s = v.strip()
        if s.startswith("dict(") and s.endswith(")"):
            call = ast.parse(s, mode="eval").body
            return {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}
        return dict(ast.literal_eval(s))
    raise InputError(f"policy_kwargs must be a mapping or a 'dict(...)' string, got {v!r}")


def load_hyperparams(
    algo: str, env_id: str, path: str | Path | None = None, fallback: str | None = None
) -> dict[str, Any]:
    """The entry of ``env_id`` in the hyperparameter file of ``algo``, merged with its drillgym section.

    Parameters
    ----------
    algo : str
        Algorithm name (``"ppo"``, ``"sac"``, ...).
    env_id : str
        Gymnasium id of the environment (the file's entry).
    path : str or path, optional
        The YAML file (rl-zoo3 layout); default ``agents/hyperparams/<algo>.yml``.
    fallback : str, optional
        The entry read when the file has none for ``env_id`` (a task's base env,
        :mod:`agents.task_training`); the entry read is returned as ``hyperparams_entry``.

    Returns
    -------
    dict
        The entry: SB3 keywords, rl-zoo3 keys and drillgym's structure keys, with ``env_kwargs`` and
        ``policy`` set.

    Raises
    ------
    MissingFileError
        The file does not exist.
    InputError
        Invalid YAML, no entry for ``env_id``, or drillgym keys outside their section.
    """
    f = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    if not f.is_file():
        raise MissingFileError(f"hyperparameter file {f} not found")
    try:
        data = load_yaml(f.read_text()) or {}
    except yaml.YAMLError as exc:
        raise InputError(f"hyperparameter file {f} is not valid YAML: {describe_parse_error(exc)}") from exc
    if env_id not in data and fallback is not None and fallback in data:
        hp = load_hyperparams(algo, fallback, f)
        hp["hyperparams_entry"] = fallback
        return hp
    if env_id not in data or env_id == STRUCTURE_SECTION:
        raise InputError(
            f"hyperparameter file {f} has no entry for {env_id!r}; "
            f"entries: {sorted(k for k in data if k != STRUCTURE_SECTION)}"
        )
    hp = dict(data[env_id] or {})
    bad = [k for k in STRUCTURE_KEYS if k in hp]
    if bad:
        raise InputError(
            f"hyperparameter file {f}: {bad} are drillgym keys, not keywords of the algorithm; "
            f"put them under the top-level section '{STRUCTURE_SECTION}: {{{env_id}: ...}}'"
        )
    hp.update((data.get(STRUCTURE_SECTION) or {}).get(env_id) or {})
    if "normalize" in hp:
        hp["normalize_obs"], hp["normalize_reward"] = _normalize_flags(hp.pop("normalize"))
    if "policy_kwargs" in hp:
        hp["policy_kwargs"] = _parse_policy_kwargs(hp["policy_kwargs"])
    hp.setdefault("env_kwargs", {})
    hp.setdefault("policy", "MlpPolicy")
    hp["hyperparams_entry"] = env_id
    return hp


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """Command-line overrides as a nested dict.

    Parameters
    ----------
    items : list of str
        ``KEY=VALUE`` items, e.g. ``["learning_rate=1e-3", "env_kwargs.motor_history=48"]``; dots nest
        the key, values are parsed as YAML.

    Returns
    -------
    dict
        The nested overrides.

    Raises
    ------
    InputError
        An item that is not ``KEY=VALUE``, invalid YAML, or two items in conflict.
    """
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"hyperparameter override must be KEY=VALUE, got {item!r}")
        try:
            v = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise InputError(
                f"hyperparameter override {item!r}: value is not valid YAML ({describe_parse_error(exc)})"
            ) from exc
        if isinstance(v, str):  # YAML 1.1 reads '1e-3' as a string
            try:
                v = float(v)
            except ValueError:
                pass
        *parents, leaf = key.split(".")
        d = out
        for p in parents:
            d = d.setdefault(p, {})
            if not isinstance(d, dict):
                raise InputError(f"hyperparameter override {item!r} conflicts with another one")
        if leaf in d:
            raise InputError(f"hyperparameter override {item!r}: {key!r} is given twice (or beside its parts)")
        d[leaf] = v
    return out


def apply_overrides(hp: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``hp`` with ``overrides`` merged in (nested dicts such as env_kwargs are merged key by key).

    Parameters
    ----------
    hp : dict
        Hyperparameters (:func:`load_hyperparams`).
    overrides : dict
        Entries replacing those of ``hp`` (:func:`parse_overrides`).

    Returns
    -------
    dict
        A merged copy; ``hp`` is not changed.
    """
    out = dict(hp)
    for k, v in overrides.items():
        out[k] = apply_overrides(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    if "policy_kwargs" in overrides:
        out["policy_kwargs"] = _parse_policy_kwargs(out["policy_kwargs"])
    return out
