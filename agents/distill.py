"""Teacher -> student distillation (DAgger): a privileged teacher that sees the simulated *full* state,
taught to a network that sees only what the rig's motor side gives (the student: the model's own
observation, e.g. 'motor').

Teachers: an exported ``policy.npz`` trained on the 'full' observation (e.g. PPO, ``ppo_teacher.yml``),
``'flatness'``: the hand-made full-state law of :class:`agents.teachers.FlatnessTeacher` (stateful:
it is reset per rig when that rig's episode ends), or ``'lqg-2enc'`` (``'observer'``): the classical two-encoder LQG
(:class:`controllers.two_encoder.TwoEncoderLQG`) run *in shadow* (:class:`agents.teachers.ShadowTeacher`): it
reads the encoder angles the student's observation carries, its Kalman filter predicts with the voltage
actually executed (the student's, when the student drives), and its voltage is the label; a student with
the same measurements and enough memory (``frame_stack``, the motor-angle integral and the command
schedule of its reference) can reproduce it.

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
from typing import Any, NamedTuple

import numpy as np

from drillgym.errors import InputError

from .command import schedule_of
from .curriculum import LowTargets
from .envs import episode_batch

__all__ = ["distill", "Teacher"]


class Teacher(NamedTuple):
    """A teacher on a batch of rigs, as the DAgger loop drives it.

    ``actions(obs)``: the labels (normalised voltages in [-1, 1], (n,)) for the student's observations
    ``obs`` (n, obs_dim) of the rigs now; ``reset(index, obs)``: the rigs ``index`` start a new episode, ``obs``
    the observations of the batch after their reset; ``applied(a)``: the normalised actions (n,) the rigs
    execute over the period just begun (after ``actions``).
    """

    actions: Callable[[np.ndarray], np.ndarray]
    reset: Callable[[np.ndarray, np.ndarray], None]
    applied: Callable[[np.ndarray], None]


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
    frame_stack: int = 1,
    whiten: float = 0.0,
    low_targets: dict[str, float] | None = None,
    bias: float = 0.0,
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
        ``"flatness"``, ``"lqg-2enc"`` or ``"observer"`` (:mod:`agents.teachers`; options in ``teacher_kwargs``)
        or the path of an exported full-state policy.
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
        Options of the ``"flatness"`` teacher, or keywords of the shadow controller (``"lqg-2enc"``, ``"observer"``).
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
    frame_stack : int, optional
        The model's observation holds the last ``frame_stack`` observations (with ``motor_integral``: stacked
        by :class:`agents.envs.MotorIntegralVecEnv`, the integral once at the end; else SB3's
        ``VecFrameStack``), as :func:`agents.envs.make_training_env` builds it.
    whiten : float, optional
        > 0: the regression preconditions the student's inputs (:class:`_Whitening`, from the first round's
        states; the covariance's eigenvalues floored at ``whiten`` times the largest), folded into the first
        layer's weights whenever the model is handed out (``on_round``, the end): the deployed network stays a
        plain MLP on the raw observation.  0: none.
    bias : float, optional
        Standard deviation of a constant offset on the executed actions (normalised), drawn per rig and episode
        (the labels stay the teacher's clean actions): a steady error the teacher's integral corrects, so the
        data cover the integral's range.
    low_targets : dict, optional
        ``{fraction, below}``: that fraction of the episodes' targets drawn uniformly below ``below`` (rad/s)
        instead of the env's (or task's) uniform range (:class:`agents.curriculum.LowTargets`; training only).
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
    task_model = kw.pop("model", None) if task is not None else None  # a task's nominal model (benchmark_env)
    if task is not None:  # the task's options and training plants (its plants are fixed: no population)
        if population is not None:
            raise InputError(f"task {task.id} fixes its plants: distill without a population")
        kw = {**task_env_kwargs(task, kw), **task_model_options(task, task_model)}
    if population is not None:
        from .population import population_env_kwargs, use_population

        kw = population_env_kwargs(kw, population)
    venv = make_sb3_vec(base_env_id(env_id), n_envs, **kw)
    if population is not None:
        use_population(venv, population, nominal_fraction, nominal_below)
    if task is not None:
        install_task_plants(venv, task, task_model)
    integral = None
    schedule = schedule_of(command, motor_integral)
    if motor_integral:
        from .envs import MotorIntegralVecEnv

        venv = integral = MotorIntegralVecEnv(
            venv, float(venv.venv.options.control_dt), command=schedule, frames=frame_stack
        )
    elif frame_stack > 1:
        from stable_baselines3.common.vec_env import VecFrameStack

        venv = VecFrameStack(venv, frame_stack)
    if privileged:
        from .privileged import PrivilegedObsVecEnv

        venv = PrivilegedObsVecEnv(venv)
    venv.seed(seed)
    batch = episode_batch(venv)
    curriculum = LowTargets.from_config(low_targets)
    if curriculum is not None:
        curriculum.install(batch)
    teach = _teacher(teacher, n_envs, batch, teacher_kwargs or {}, integral, frame_stack, env_kwargs.get("model"))

    policy = model.policy
    params = list(policy.mlp_extractor.policy_net.parameters()) + list(policy.action_net.parameters())
    opt = th.optim.Adam(params, lr=lr)
    if not (np.isfinite(whiten) and 0.0 <= whiten < 1.0):
        raise InputError(f"whiten must be an eigenvalue floor in [0, 1) (0: none), got {whiten!r}")
    if whiten > 0 and privileged:
        raise InputError("whiten preconditions the actor's whole observation: not with the privileged critic")
    white: _Whitening | None = None

    def actor(x: th.Tensor) -> th.Tensor:
        feats = policy.pi_features_extractor(x)
        if white is not None:
            feats = white(feats)
        return policy.action_net(policy.mlp_extractor.forward_actor(feats))[:, 0]

    def mean_action(obs: np.ndarray) -> th.Tensor:
        return actor(th.as_tensor(obs, dtype=th.float32))

    X: list[np.ndarray] = []
    Y: list[np.ndarray] = []
    obs = venv.reset()
    teach.reset(np.arange(n_envs), obs)
    rng = np.random.default_rng(seed)
    mse = float("nan")
    if not (0.0 <= beta <= 1.0 and noise >= 0.0 and bias >= 0.0):
        raise InputError(
            f"beta must be in [0, 1], noise and bias >= 0, got beta={beta!r}, noise={noise!r}, bias={bias!r}"
        )
    offset = bias * rng.standard_normal(n_envs) if bias > 0 else np.zeros(n_envs)  # each episode's action offset
    for it in range(iterations):
        for g in opt.param_groups:
            g["lr"] = round_learning_rate(lr, lr_final, it, iterations)
        by_teacher = rng.random(n_envs) < (1.0 if it == 0 else beta**it)
        for _ in range(steps):
            a_t = teach.actions(obs)
            X.append(obs.copy())
            Y.append(a_t.astype(np.float32))
            a = a_t
            if not by_teacher.all():
                with th.no_grad():
                    a = np.where(by_teacher, a_t, mean_action(obs).numpy())
            if noise > 0:
                a = a + noise * rng.standard_normal(n_envs)
            a = np.clip(a + offset, -1.0, 1.0)
            teach.applied(a)
            obs, _, done, _ = venv.step(a.reshape(-1, 1))
            if done.any():
                teach.reset(np.flatnonzero(done), obs)
                if bias > 0:
                    offset[done] = bias * rng.standard_normal(int(done.sum()))
        data_x = th.as_tensor(np.concatenate(X), dtype=th.float32)
        data_y = th.as_tensor(np.concatenate(Y), dtype=th.float32)
        n = data_x.shape[0]
        if whiten > 0 and white is None:  # from the first round's states (the teacher's)
            white = _Whitening(data_x.numpy(), whiten, policy.mlp_extractor.policy_net[0])
        for _ in range(epochs):
            perm = th.as_tensor(rng.permutation(n))
            for k in range(0, n, batch_size):
                idx = perm[k : k + batch_size]
                pred = actor(data_x[idx])
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
            if white is None:
                on_round(it, mse)
            else:
                with white.folded():
                    on_round(it, mse)
    venv.close()
    if white is not None:
        white.fold()
    return {"mse": mse, "states": int(sum(len(x) for x in X))}


class _Whitening:
    """The fixed affine map ``x -> M (x - mu)`` of the student's inputs the regression trains through.

    ``mu``: the inputs' mean; ``M = V diag((e + floor max e)^-1/2) V^T diag(1/sd)``, the inverse square
    root of the standardised inputs' covariance (eigen-decomposition ``V, e``), its eigenvalues floored at
    ``floor`` times the largest.  An entry constant in those states (e.g. an integral still at 0) is left out of
    the decorrelation and passes unscaled, not amplified by the floor's (floor max e)^-1/2.  A stacked history is
    strongly correlated (consecutive frames differ by little) and the labels hinge on those small differences:
    plain gradient steps on the raw inputs fit them poorly.  The map is linear, so the first layer ``W, b`` on
    whitened inputs is the layer ``W M, b - W M mu`` on the raw ones (:meth:`fold`): the deployed network is a
    plain MLP.

    Parameters
    ----------
    x : ndarray
        The inputs (states, dim) it is computed from.
    floor : float
        Eigenvalue floor, relative to the largest (> 0).
    layer : torch.nn.Linear
        The first layer of the actor, trained on the whitened inputs.
    """

    def __init__(self, x: np.ndarray, floor: float, layer) -> None:
        import torch as th

        if not isinstance(layer, th.nn.Linear):
            raise InputError(f"whiten needs an actor whose first layer is linear, got {layer}")
        x = np.asarray(x, dtype=np.float64)
        mu, sd = x.mean(axis=0), x.std(axis=0)
        const = sd <= 1e-6
        sd = np.where(const, 1.0, sd)
        cov = np.atleast_2d(np.cov(((x - mu) / sd).T))
        cov[const, :], cov[:, const] = 0.0, 0.0
        cov[const, const] = 1.0  # an entry constant in these states (e.g. an integral still at 0) passes unscaled
        e, V = np.linalg.eigh(cov)
        e = np.maximum(e, 0.0)
        M = (V / np.sqrt(e + floor * e.max())) @ V.T / sd[None, :]
        self.mu = th.as_tensor(mu, dtype=th.float32)
        self.M = th.as_tensor(M, dtype=th.float32)
        self.layer = layer

    def __call__(self, x):
        return (x - self.mu) @ self.M.T

    def fold(self) -> None:
        """Merge the map into the first layer (for good: the actor then reads raw inputs)."""
        import torch as th

        with th.no_grad():
            w = self.layer.weight @ self.M
            self.layer.bias.sub_(w @ self.mu)
            self.layer.weight.copy_(w)

    def folded(self):
        """A context in which the first layer reads raw inputs (the weights restored on exit)."""
        from contextlib import contextmanager

        import torch as th

        @contextmanager
        def ctx():
            saved = self.layer.weight.detach().clone(), self.layer.bias.detach().clone()
            self.fold()
            try:
                yield
            finally:
                with th.no_grad():
                    self.layer.weight.copy_(saved[0])
                    self.layer.bias.copy_(saved[1])

        return ctx()


def round_learning_rate(lr: float, lr_final: float | None, it: int, iterations: int) -> float:
    """Adam's learning rate in DAgger round ``it`` (0-based) of ``iterations``: ``lr`` falling geometrically
    to ``lr_final`` in the last round (constant ``lr`` if ``lr_final`` is None)."""
    if lr_final is None or iterations <= 1:
        return lr
    if not (lr > 0 and lr_final > 0):
        raise InputError(f"learning rates must be positive, got lr={lr!r}, lr_final={lr_final!r}")
    return lr * (lr_final / lr) ** (it / (iterations - 1))


def _teacher(
    teacher: str | Path, n: int, batch, options: dict[str, Any], integral=None, frames: int = 1, model: Any = None
) -> Teacher:
    """The teacher on the rigs of ``batch``; ``integral``: the :class:`agents.integral.MotorIntegralVecEnv`
    whose integral the flatness teacher uses; ``frames``: the observations stacked in the student's; ``model``: the
    rigs' model when training was given one (``train --model``): a shadow controller is built on it, as
    ``controllers.make(name, model=...)`` (one it cannot use is refused in one line)."""
    from .teachers import SHADOW_CONTROLLERS

    ignore = lambda *args: None  # noqa: E731 - a teacher without use for the executed action or the reset
    if str(teacher) in SHADOW_CONTROLLERS:
        from .teachers import ShadowTeacher

        o = batch.options
        top = max(float(o.omega_ref_range[1]), float(o.omega_ref or 0.0))  # the highest target of an episode
        if model is not None and "model" not in options:
            options = {**options, "model": model}
        t = ShadowTeacher(str(teacher), n, o.control_dt, list(batch.obs_model.names), top=top, **options)
        if t.given is not None and integral is None:
            raise InputError("given_integral: the teacher takes the student's integral (motor_integral: true)")
        dim = batch.obs_model.dim

        def frame(obs: np.ndarray) -> np.ndarray:  # the newest sensors observation of the student's
            return np.asarray(obs)[:, (frames - 1) * dim : frames * dim]

        def z(obs: np.ndarray) -> np.ndarray | None:  # the student's integral, its observation's last entry
            return None if t.given is None else np.asarray(obs)[:, -1]

        return Teacher(
            lambda obs: t.act(frame(obs), batch.omega_ref, z(obs)),
            lambda index, obs: t.reset(index, frame(obs), batch.omega_ref),
            t.applied,
        )
    if str(teacher) == "flatness":
        from drillgym.params import N_PARAMS

        from .teachers import FlatnessTeacher

        t = FlatnessTeacher(n, batch.options.rig_params, batch.options.control_dt, **options)
        s = batch.system

        def reset(index: np.ndarray, obs: np.ndarray) -> None:
            if t.per_plant:  # the rigs' new episodes' true base parameters (drawn at their reset)
                t.set_plants(index, s.params_matrix[index, :N_PARAMS])
            # the student's command (the scheduled target) is the teacher's
            t.reset(index, (batch.omega_ref if integral is None else integral.command_now)[index])

        if integral is None:
            return Teacher(lambda obs: t.act(s.omega_u, s.alpha, s.omega_l), reset, ignore)
        # the student's integral is the teacher's
        return Teacher(
            lambda obs: t.act(s.omega_u, s.alpha, s.omega_l, integral.z, target=integral.command_now), reset, ignore
        )
    from drillgym.envs.observation import FullObservation

    from .export import ExportedPolicy

    if options:
        raise InputError("teacher options apply to the teachers by name only (flatness, lqg-2enc, observer)")
    teach = ExportedPolicy.load(teacher)
    if teach.config["hyperparams"]["env_kwargs"].get("observation", "full") != "full":
        raise InputError(f"teacher {teacher} was not trained on the 'full' observation")
    full = FullObservation(n, replace(batch.options, observation="full"))
    tobs = np.zeros((n, full.dim), dtype=np.float32)

    def actions(obs: np.ndarray) -> np.ndarray:
        full.observe(batch.system.Y, batch.S[:, 0], batch.omega_ref, tobs, batch.rngs)
        return teach.act(tobs)[:, 0]

    return Teacher(actions, ignore, ignore)
