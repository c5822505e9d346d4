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
    """``agent:PATH`` hook of :func:`controllers.make` (see :func:`agents.loader.load_controller`)."""
    from .loader import load_controller as _load

    return _load(path, **kw)


def load_policy(path: str):
    """Exported policy of PATH (see :func:`agents.loader.load_policy`)."""
    from .loader import load_policy as _load

    return _load(path)
