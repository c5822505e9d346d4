"""Teacher -> student distillation (DAgger): a policy trained on the simulated *full* state (the teacher,
an exported ``policy.npz`` of the 'full' observation) taught to a network that sees only what the rig's
motor side gives (the student: the model's own observation, e.g. 'motor').

Training only: the student is the SB3 model's actor, so it is exported and deployed as any other
policy (no teacher, no controller inside).  DAgger (Ross et al. 2011): the student drives the rigs
(the teacher for the first iteration's rollouts), every visited state is labelled with the teacher's
action on the true state, the labels are aggregated, and the actor is regressed on them (mean squared
error of its mean action, actions in [-1, 1]).  The teacher's observation is rebuilt from the simulator's
state each period (:class:`drillgym.envs.observation.FullObservation`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["distill"]


def distill(model, env_id: str, env_kwargs: dict[str, Any], teacher: str | Path, *, n_envs: int = 64,
            iterations: int = 8, steps: int = 500, epochs: int = 4, batch_size: int = 4096, lr: float = 1e-3,
            seed: int = 0, privileged: bool = False, log=None) -> dict[str, float]:
    """Regress the actor of the SB3 ``model`` (PPO/MLP, its env's observation) on the ``teacher``'s actions.

    ``iterations`` DAgger rounds of ``steps`` periods on ``n_envs`` rigs of ``env_id`` with ``env_kwargs``
    (domain randomisation included); ``epochs`` passes of Adam (``lr``) over the aggregated data per round.
    ``privileged``: the model's observation carries the privileged critic's entries (ignored by the actor).
    Returns the last round's mean squared action error and the number of labelled states."""
    import torch as th

    from drillgym.envs.observation import FullObservation
    from drillgym.envs.sb3 import make_sb3_vec

    from .export import ExportedPolicy

    teach = ExportedPolicy.load(teacher)
    if teach.config["hyperparams"]["env_kwargs"].get("observation", "full") != "full":
        raise ValueError(f"teacher {teacher} was not trained on the 'full' observation")
    venv = make_sb3_vec(env_id, n_envs, **{**env_kwargs, "normalize_action": True})
    if privileged:
        from .privileged import PrivilegedObsVecEnv

        venv = PrivilegedObsVecEnv(venv)
    venv.seed(seed)
    batch = (venv.venv if privileged else venv).venv.batch
    full = FullObservation(n_envs, replace(batch.options, observation="full"))
    tobs = np.zeros((n_envs, full.dim), dtype=np.float32)

    def teacher_actions() -> np.ndarray:
        full.observe(batch.system.Y, batch.S[:, 0], batch.omega_ref, tobs, batch.rngs)
        return teach.act(tobs)[:, 0]

    policy = model.policy
    params = list(policy.mlp_extractor.policy_net.parameters()) + list(policy.action_net.parameters())
    opt = th.optim.Adam(params, lr=lr)

    def mean_action(obs: np.ndarray) -> th.Tensor:
        x = th.as_tensor(obs, dtype=th.float32)
        feats = policy.pi_features_extractor(x)
        return policy.action_net(policy.mlp_extractor.forward_actor(feats))[:, 0]

    X: list[np.ndarray] = []
    Y: list[np.ndarray] = []
    obs = venv.reset()
    rng = np.random.default_rng(seed)
    mse = float("nan")
    for it in range(iterations):
        for _ in range(steps):
            a_t = teacher_actions()
            X.append(obs.copy())
            Y.append(a_t.copy())
            if it == 0:
                a = a_t
            else:
                with th.no_grad():
                    a = np.clip(mean_action(obs).numpy(), -1.0, 1.0)
            obs, _, _, _ = venv.step(a.reshape(-1, 1))
        data_x = th.as_tensor(np.concatenate(X), dtype=th.float32)
        data_y = th.as_tensor(np.concatenate(Y), dtype=th.float32)
        n = data_x.shape[0]
        for _ in range(epochs):
            perm = th.as_tensor(rng.permutation(n))
            for k in range(0, n, batch_size):
                idx = perm[k:k + batch_size]
                x = data_x[idx]
                feats = policy.pi_features_extractor(x)
                pred = policy.action_net(policy.mlp_extractor.forward_actor(feats))[:, 0]
                loss = th.mean((pred.clamp(-1.5, 1.5) - data_y[idx]) ** 2)
                opt.zero_grad()
                loss.backward()
                opt.step()
        with th.no_grad():
            mse = float(th.mean((mean_action(data_x[-steps * n_envs:].numpy()).clamp(-1, 1)
                                 - data_y[-steps * n_envs:]) ** 2))
        if log is not None:
            log(f"DAgger round {it + 1}/{iterations}: {n} labelled states, action MSE {mse:.4f}")
    venv.close()
    return {"mse": mse, "states": int(sum(len(x) for x in X))}
