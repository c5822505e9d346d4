"""Teacher -> student distillation (DAgger): a privileged teacher that sees the simulated *full* state,
taught to a network that sees only what the rig's motor side gives (the student: the model's own
observation, e.g. 'motor').

Teachers: an exported ``policy.npz`` trained on the 'full' observation (e.g. PPO, ``ppo_teacher.yml``),
or ``'flatness'``: the hand-made full-state law of :class:`agents.teachers.FlatnessTeacher` (stateful:
it is reset per rig when that rig's episode ends).

Training only: the student is the SB3 model's actor, so it is exported and deployed as any other
policy (no teacher, no controller inside).  DAgger (Ross et al. 2011): the student drives the rigs
(the teacher for the first iteration's rollouts), every visited state is labelled with the teacher's
action on the true state, the labels are aggregated, and the actor is regressed on them (mean squared
error of its mean action, actions in [-1, 1]).  ``population``: each episode's rig is drawn from the
plant population's uncertainty set (:mod:`agents.population`; lags and delays included).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import InputError

from .command import schedule_of
from .envs import episode_batch

__all__ = ["distill"]


def distill(
    model,
    env_id: str,
    env_kwargs: dict[str, Any],
    teacher: str | Path,
    *,
    n_envs: int = 64,
    iterations: int = 8,
    steps: int = 500,
    epochs: int = 4,
    batch_size: int = 4096,
    lr: float = 1e-3,
    seed: int = 0,
    privileged: bool = False,
    population: str | None = None,
    nominal_fraction: float = 0.0,
    nominal_below: float = 0.0,
    teacher_kwargs: dict[str, Any] | None = None,
    beta: float = 0.0,
    noise: float = 0.0,
    motor_integral: bool = False,
    command: dict[str, float] | None = None,
    lr_final: float | None = None,
    log=None,
    on_round: Callable[[int, float], None] | None = None,
) -> dict[str, float]:
    """Regress the actor of the SB3 ``model`` (PPO/MLP, its env's observation) on the ``teacher``'s actions.

    ``iterations`` DAgger rounds of ``steps`` periods on ``n_envs`` rigs (domain randomisation included),
    each followed by ``epochs`` passes of Adam over the aggregated data.

    Parameters
    ----------
    model : stable_baselines3.common.base_class.BaseAlgorithm
        The student: a PPO model with an MLP policy on its env's observation.
    env_id : str
        Gymnasium id of the environment.
    env_kwargs : dict
        Options of the environment (:class:`drillgym.envs.EnvOptions`).
    teacher : str or path
        ``"flatness"`` (:mod:`agents.teachers`; options in ``teacher_kwargs``) or the path of an exported
        full-state policy.
    n_envs : int, optional
        Rigs stepped together.  Default 64.
    iterations : int, optional
        DAgger rounds.  Default 8.
    steps : int, optional
        Control periods per round.  Default 500.
    epochs : int, optional
        Passes over the aggregated data per round.  Default 4.
    batch_size : int, optional
        Minibatch size of the regression.
    lr : float, optional
        Adam's learning rate (in the first round).  Default 1e-3.
    seed : int, optional
        Seed of the rigs and of the regression.
    privileged : bool, optional
        The model's observation carries the privileged critic's entries (ignored by the actor).
    population : str, optional
        An uncertainty set (``"default"`` or a YAML path) the rigs are drawn from.
    nominal_fraction : float, optional
        Fraction of the episodes on the nominal rig instead of a drawn plant.
    nominal_below : float, optional
        Every episode whose target is below this speed (rad/s) runs the nominal rig.
    teacher_kwargs : dict, optional
        Options of the ``"flatness"`` teacher.
    beta : float, optional
        In round i > 0 a fraction ``beta**i`` of the rigs is still driven by the teacher (DAgger's mixing;
        0: the student drives every rig after the first round).
    noise : float, optional
        Standard deviation of Gaussian noise on the executed actions (normalised; the labels stay the
        teacher's clean actions), so that the data cover the states a slightly wrong action leads to.
    motor_integral : bool, optional
        The model's observation ends with the motor-angle tracking integral (:mod:`agents.integral`); the
        ``"flatness"`` teacher then uses that integral as its own.
    command : dict, optional
        Settings of the command schedule (:mod:`agents.command`; needs ``motor_integral``): the student sees
        the scheduled speed command as its target and the ``"flatness"`` teacher tracks it.
    lr_final : float, optional
        The learning rate falls geometrically from ``lr`` in the first round to this in the last
        (:func:`round_learning_rate`); None: constant.
    log : callable, optional
        ``log(message: str)``: one line per round.
    on_round : callable, optional
        ``on_round(i, mse)`` after round i's regression (0-based) with its action error, e.g. to snapshot
        or validate the student round by round.

    Returns
    -------
    dict
        ``mse``: the last round's mean squared action error; ``states``: the number of labelled states.
    """
    import torch as th

    from drillgym.envs.sb3 import make_sb3_vec

    from .task_training import base_env_id, install_task_plants, task_env_kwargs, task_model_options, task_of

    task = task_of(env_id)
    kw = {**env_kwargs, "normalize_action": True}
    if task is not None:  # the task's options and training plants (its plants are fixed: no population)
        if population is not None:
            raise InputError(f"task {task.id} fixes its plants: distill without a population")
        kw = {**task_env_kwargs(task, kw), **task_model_options(task)}
    if population is not None:
        from .population import population_env_kwargs, use_population

        kw = population_env_kwargs(kw, population)
    venv = make_sb3_vec(base_env_id(env_id), n_envs, **kw)
    if population is not None:
        use_population(venv, population, nominal_fraction, nominal_below)
    if task is not None:
        install_task_plants(venv, task)
    integral = None
    schedule = schedule_of(command, motor_integral)
    if motor_integral:
        from .envs import MotorIntegralVecEnv

        venv = integral = MotorIntegralVecEnv(venv, float(venv.venv.options.control_dt), command=schedule)
    if privileged:
        from .privileged import PrivilegedObsVecEnv

        venv = PrivilegedObsVecEnv(venv)
    venv.seed(seed)
    batch = episode_batch(venv)
    teacher_actions, teacher_reset = _teacher(teacher, n_envs, batch, teacher_kwargs or {}, integral)

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
    teacher_reset(np.arange(n_envs))
    rng = np.random.default_rng(seed)
    mse = float("nan")
    if not (0.0 <= beta <= 1.0 and noise >= 0.0):
        raise InputError(f"beta must be in [0, 1] and noise >= 0, got beta={beta!r}, noise={noise!r}")
    for it in range(iterations):
        for g in opt.param_groups:
            g["lr"] = round_learning_rate(lr, lr_final, it, iterations)
        by_teacher = rng.random(n_envs) < (1.0 if it == 0 else beta**it)
        for _ in range(steps):
            a_t = teacher_actions()
            X.append(obs.copy())
            Y.append(a_t.astype(np.float32))
            a = a_t
            if not by_teacher.all():
                with th.no_grad():
                    a = np.where(by_teacher, a_t, mean_action(obs).numpy())
            if noise > 0:
                a = a + noise * rng.standard_normal(n_envs)
            a = np.clip(a, -1.0, 1.0)
            obs, _, done, _ = venv.step(a.reshape(-1, 1))
            if done.any():
                teacher_reset(np.flatnonzero(done))
        data_x = th.as_tensor(np.concatenate(X), dtype=th.float32)
        data_y = th.as_tensor(np.concatenate(Y), dtype=th.float32)
        n = data_x.shape[0]
        for _ in range(epochs):
            perm = th.as_tensor(rng.permutation(n))
            for k in range(0, n, batch_size):
                idx = perm[k : k + batch_size]
                x = data_x[idx]
                feats = policy.pi_features_extractor(x)
                pred = policy.action_net(policy.mlp_extractor.forward_actor(feats))[:, 0]
                loss = th.mean((pred.clamp(-1.5, 1.5) - data_y[idx]) ** 2)
                opt.zero_grad()
                loss.backward()
                opt.step()
        with th.no_grad():
            mse = float(
                th.mean((mean_action(data_x[-steps * n_envs :].numpy()).clamp(-1, 1) - data_y[-steps * n_envs :]) ** 2)
            )
        if log is not None:
            log(f"DAgger round {it + 1}/{iterations}: {n} labelled states, action MSE {mse:.4f}")
        if on_round is not None:
            on_round(it, mse)
    venv.close()
    return {"mse": mse, "states": int(sum(len(x) for x in X))}


def round_learning_rate(lr: float, lr_final: float | None, it: int, iterations: int) -> float:
    """Adam's learning rate in DAgger round ``it`` (0-based) of ``iterations``: ``lr`` falling geometrically
    to ``lr_final`` in the last round (constant ``lr`` if ``lr_final`` is None)."""
    if lr_final is None or iterations <= 1:
        return lr
    if not (lr > 0 and lr_final > 0):
        raise InputError(f"learning rates must be positive, got lr={lr!r}, lr_final={lr_final!r}")
    return lr * (lr_final / lr) ** (it / (iterations - 1))


def _teacher(teacher: str | Path, n: int, batch, options: dict[str, Any], integral=None):
    """(actions(), reset(index)) of the teacher on the rigs of ``batch`` (actions in [-1, 1], (n,));
    ``integral``: the :class:`agents.integral.MotorIntegralVecEnv` whose integral the flatness teacher uses."""
    if str(teacher) == "flatness":
        from drillgym.params import N_PARAMS

        from .teachers import FlatnessTeacher

        t = FlatnessTeacher(n, batch.options.rig_params, batch.options.control_dt, **options)
        s = batch.system

        def reset(index: np.ndarray) -> None:
            if t.per_plant:  # the rigs' new episodes' true base parameters (drawn at their reset)
                t.set_plants(index, s.params_matrix[index, :N_PARAMS])
            # the student's command (the scheduled target) is the teacher's
            t.reset(index, (batch.omega_ref if integral is None else integral.command_now)[index])

        if integral is None:
            return lambda: t.act(s.omega_u, s.alpha, s.omega_l), reset
        # the student's integral is the teacher's
        return lambda: t.act(s.omega_u, s.alpha, s.omega_l, integral.z, target=integral.command_now), reset
    from drillgym.envs.observation import FullObservation

    from .export import ExportedPolicy

    if options:
        raise InputError("teacher options apply to the 'flatness' teacher only")
    teach = ExportedPolicy.load(teacher)
    if teach.config["hyperparams"]["env_kwargs"].get("observation", "full") != "full":
        raise InputError(f"teacher {teacher} was not trained on the 'full' observation")
    full = FullObservation(n, replace(batch.options, observation="full"))
    tobs = np.zeros((n, full.dim), dtype=np.float32)

    def actions() -> np.ndarray:
        full.observe(batch.system.Y, batch.S[:, 0], batch.omega_ref, tobs, batch.rngs)
        return teach.act(tobs)[:, 0]

    return actions, lambda index: None
