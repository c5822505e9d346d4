"""Hyperparameters in the rl-zoo3 layout: one YAML file per algorithm, one entry per env id.

``agents/hyperparams/<algo>.yml``::

    drillgym/Torsional-v0:
      n_envs: 32                 # rigs of the batched DrillVectorEnv
      n_timesteps: !!float 1e6   # default training length
      policy: MlpPolicy
      learning_rate: !!float 3e-4
      ...                        # any keyword of the SB3 algorithm
      policy_kwargs: {net_arch: [64, 64]}
      env_kwargs: {observation: motor, randomize: 0.2, ...}   # drillgym EnvOptions
      residual: 2.0              # drillgym: action = correction (V) on the feedforward voltage; null = plain voltage
      startup: [5.0, 3.0, 15.0]  # drillgym: feedforward start-up schedule (kick V, hold s, ramp s), see agents/residual.py
      base: observer             # drillgym: the residual corrects the observer controller (agents/observer_residual.py)
      observer: {}               # drillgym: keywords of that controller (controllers.observer.ObserverController)
      normalize_reward: false    # drillgym: VecNormalize on rewards only (no run-time state)
      frame_stack: 1             # drillgym: VecFrameStack depth (the 'motor' mode already holds a history)

As in rl-zoo3, ``policy_kwargs`` may also be a string (``"dict(net_arch=[64, 64])"``);
it is parsed with :func:`ast.literal_eval`-like rules (no code is executed).
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Any

import yaml

__all__ = ["HYPERPARAMS_DIR", "load_hyperparams", "parse_overrides", "apply_overrides", "DRILLGYM_KEYS"]

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
#: keys of an entry that are not keywords of the SB3 algorithm
DRILLGYM_KEYS = ("n_envs", "n_timesteps", "policy", "env_kwargs", "residual", "startup", "base", "observer",
                 "frame_stack", "normalize_reward")


def _parse_policy_kwargs(v: Any) -> dict:
    if isinstance(v, dict):
        return dict(v)
    if isinstance(v, str):
        s = v.strip()
        if s.startswith("dict(") and s.endswith(")"):
            call = ast.parse(s, mode="eval").body
            return {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}
        return dict(ast.literal_eval(s))
    raise ValueError(f"policy_kwargs must be a mapping or a 'dict(...)' string, got {v!r}")


def load_hyperparams(algo: str, env_id: str, path: "str | Path | None" = None) -> dict[str, Any]:
    """The entry of ``env_id`` in the hyperparameter file of ``algo`` (default ``agents/hyperparams/<algo>.yml``)."""
    f = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    if not f.is_file():
        raise FileNotFoundError(f"hyperparameter file {f} not found")
    try:
        data = yaml.safe_load(f.read_text()) or {}
    except yaml.YAMLError as exc:
        raise ValueError(f"hyperparameter file {f} is not valid YAML: {exc}") from exc
    if env_id not in data:
        raise ValueError(f"hyperparameter file {f} has no entry for {env_id!r}; entries: {sorted(data)}")
    hp = dict(data[env_id] or {})
    if "policy_kwargs" in hp:
        hp["policy_kwargs"] = _parse_policy_kwargs(hp["policy_kwargs"])
    hp.setdefault("env_kwargs", {})
    hp.setdefault("policy", "MlpPolicy")
    return hp


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["learning_rate=1e-3", "env_kwargs.motor_history=48"]`` -> a nested dict (values parsed as YAML)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"hyperparameter override must be KEY=VALUE, got {item!r}")
        try:
            v = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise ValueError(f"hyperparameter override {item!r}: value is not valid YAML ({exc})") from exc
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
                raise ValueError(f"hyperparameter override {item!r} conflicts with another one")
        d[leaf] = v
    return out


def apply_overrides(hp: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``hp`` with ``overrides`` merged in (nested dicts such as env_kwargs are merged key by key)."""
    out = dict(hp)
    for k, v in overrides.items():
        out[k] = apply_overrides(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    if "policy_kwargs" in overrides:
        out["policy_kwargs"] = _parse_policy_kwargs(out["policy_kwargs"])
    return out
