"""RL agents for the drill-string rig: training (stable-baselines3), export, and the Controller adapter.

* :mod:`.hyperparams` - rl-zoo3 style YAML hyperparameters (``agents/hyperparams/<algo>.yml``)
* :mod:`.residual` - the policy structure: a correction on the feedforward voltage u_ff(omega_ref)
* :mod:`.observer_residual` - the policy structure of the kept agent: a correction on the ``observer``
  controller's voltage, the policy seeing that controller's estimates (motor angle only)
* :mod:`.privileged` - privileged critic for PPO (the critic also sees the lower disc; training only)
* :mod:`.distill` - teacher (full state) -> student (motor side) distillation by DAgger (training only)
* :mod:`.teachers` - the hand-made full-state teacher (flatness law on the true state; training only)
* :mod:`.integral` - the motor-angle tracking integral, an observation entry of the motor side
* :mod:`.population` - domain randomisation over the plant population's uncertainty set (training only)
* :mod:`.evaluation` - the lowest held target from rest of a trained policy (the controllers' harness)
* :mod:`.seeds` - several seeds: table with IQM and bootstrap interval, learning curves
* :mod:`.envs` - batched training envs (DrillVectorEnv through the SB3 adapter)
* :mod:`.train` - ``train(env_id, algo, out, ...)``: seeds, TensorBoard, progress bar, checkpoints, resume
* :mod:`.export` - numpy export of the deterministic policy (no torch on the rig)
* :mod:`.controller` - :class:`AgentController`: measurements -> env observation -> policy -> volts
* :mod:`.switched` - target-switched policies: learned networks, each serving a band of target speeds
* :mod:`.loader` - ``load_controller(path, ...)``: the ``agent:PATH`` hook of :func:`controllers.make`

``import agents`` is light (numpy only); torch and SB3 load when training or reading a ``.zip``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["load_controller", "load_policy", "KEPT_POLICY", "LEARNED_POLICY"]

#: the kept learned policy (motor side only; two learned networks chosen by the target, agents/switched.py):
#: agents/policies/torsional_motor_learned
LEARNED_POLICY = Path(__file__).resolve().parent / "policies" / "torsional_motor_learned" / "policy.npz"
#: the policy kept in the repository (``agent:`` + this path works in ``drillgym evaluate``)
KEPT_POLICY = Path(__file__).resolve().parent / "policies" / "torsional_motor_residual_observer" / "policy.npz"


def load_controller(path: str, **kw):
    """The agent at PATH as a :class:`controllers.Controller` (the ``agent:PATH`` hook of :func:`controllers.make`).

    Parameters
    ----------
    path : str
        An exported policy (``policy.npz``), a run's ``model.zip`` or a run directory.
    **kw
        ``config`` (rig configuration, default ``"torsional"``), ``omega_ref`` (target speed, rad/s),
        ``params`` (the design model) and the other keywords of :class:`controllers.Controller`.

    Returns
    -------
    AgentController or TargetSwitchedController
        The policy as a controller (a target-switched set of networks gives the switched one).

    Raises
    ------
    MissingFileError
        PATH, or a ``model.zip``'s ``config.yml``, does not exist.
    InputError
        PATH is neither ``.npz`` nor ``.zip``.

    Examples
    --------
    >>> import agents
    >>> c = agents.load_controller(str(agents.KEPT_POLICY), omega_ref=3.0)  # doctest: +SKIP
    """
    from .loader import load_controller as _load

    return _load(path, **kw)


def load_policy(path: str):
    """The exported policy of PATH (numpy only unless PATH is an SB3 ``.zip`` without ``policy.npz``).

    Parameters
    ----------
    path : str
        An exported policy (``policy.npz``: one network or a target-switched set of them), a run's
        ``model.zip`` (its ``policy.npz`` beside it is used; without one, the model is loaded with the
        run's ``config.yml`` and exported in memory) or a run directory.

    Returns
    -------
    ExportedPolicy or TargetSwitchedPolicy
        The deterministic policy: observation -> action.

    Raises
    ------
    MissingFileError
        PATH, or a ``model.zip``'s ``config.yml``, does not exist.
    InputError
        PATH is neither ``.npz`` nor ``.zip``.
    """
    from .loader import load_policy as _load

    return _load(path)
