"""``agent:PATH`` -> :class:`agents.controller.AgentController` (the hook of :func:`controllers.make`).

PATH may be an exported policy (``policy.npz``), a run's ``model.zip`` (its ``policy.npz`` beside it is
used; without one, the SB3 model is loaded with the run's ``config.yml`` and exported in memory) or a
run directory.  Only the ``.zip`` fallback needs torch and stable-baselines3.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from drillgym.errors import InputError, MissingFileError
from drillgym.io import describe_parse_error

from .controller import AgentController, TargetSwitchedController
from .export import ExportedPolicy
from .switched import TargetSwitchedPolicy, read_policy

__all__ = ["load_policy", "load_controller"]


def load_policy(path: str | Path) -> ExportedPolicy | TargetSwitchedPolicy:
    """The exported policy of PATH, as :func:`agents.load_policy`.

    Parameters
    ----------
    path : str or path
        An exported policy (``.npz``: one network or a target-switched set of them), a run's
        ``model.zip`` or a run directory.

    Returns
    -------
    ExportedPolicy or TargetSwitchedPolicy
        The deterministic policy.
    """
    p = Path(path)
    if p.is_dir():
        p = p / "policy.npz" if (p / "policy.npz").is_file() else p / "model.zip"
    if not p.exists():
        raise MissingFileError(f"agent file {p} not found")
    if p.suffix == ".npz":
        return read_policy(p)
    if p.suffix != ".zip":
        raise InputError(f"agent file {p} must be an exported policy (.npz) or an SB3 model (.zip)")
    beside = p.with_name("policy.npz")
    if beside.is_file():
        return ExportedPolicy.load(beside)
    cfg_file = p.with_name("config.yml")
    if not cfg_file.is_file():
        raise MissingFileError(f"agent {p}: no config.yml beside it (needed to rebuild the observation)")
    try:
        config = yaml.safe_load(cfg_file.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"agent {p}: {cfg_file.name} beside it cannot be read: {describe_parse_error(exc)}") from None
    if not isinstance(config, dict) or "algo" not in config:
        raise InputError(f"agent {p}: {cfg_file.name} beside it names no 'algo' (not a drillgym training run)")
    import tempfile

    from .export import export_policy
    from .train import algo_class

    try:
        model = algo_class(config["algo"]).load(p, device="cpu")
    except Exception as exc:  # noqa: BLE001 - anything SB3 cannot load is not a model it wrote
        raise InputError(
            f"agent {p}: not a readable {config['algo']} model ({type(exc).__name__}: {describe_parse_error(exc)})"
        ) from exc
    with tempfile.TemporaryDirectory() as d:
        return ExportedPolicy.load(export_policy(model, Path(d) / "policy.npz", config))


def load_controller(
    path: str, *, config: str = "torsional", omega_ref=None, params=None, **kw
) -> AgentController | TargetSwitchedController:
    """The agent at PATH as a Controller for rig configuration ``config``, as :func:`agents.load_controller`.

    Parameters
    ----------
    path : str
        An exported policy, a run's ``model.zip`` or a run directory.
    config : str, optional
        Rig configuration.  Default ``"torsional"``.
    omega_ref : float or ndarray, optional
        Target speed(s) (rad/s).
    params : RigParams, optional
        The design model; default the identified set.
    **kw
        Other keywords of :class:`controllers.Controller` (e.g. ``dt``).

    Returns
    -------
    AgentController or TargetSwitchedController
        The policy as a controller.
    """
    policy = load_policy(path)
    cls = TargetSwitchedController if isinstance(policy, TargetSwitchedPolicy) else AgentController
    return cls(policy, omega_ref, config=config, params=params, **kw)
