"""Training of SB3 agents on the drillgym environments (PPO, SAC, TD3, RecurrentPPO).

    >>> from agents.train import train
    >>> result = train("drillgym/Torsional-v0", "sac", "runs/sac", timesteps=200_000, seed=1)

Writes into ``out``: ``model.zip`` (the SB3 model), ``config.yml`` (everything needed to
rebuild the env and the policy structure: env id, algorithm, seed, hyperparameters,
env options, residual scale), ``policy.npz`` (the exported policy, :mod:`agents.export`;
MLP policies only), ``checkpoints/latest.zip`` (+ replay buffer for off-policy algorithms, reward
normalisation statistics),
refreshed every ``checkpoint_every`` steps and used by ``resume=True``, and TensorBoard logs
in ``tb/``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, EvalCallback
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from drillgym.errors import InputError, MissingFileError
from drillgym.io import create_directory

from .envs import make_training_env
from .hyperparams import algorithm_kwargs, apply_overrides, load_hyperparams
from .run_model import check_resumed_model, with_model
from .task_training import base_env_id, check_task_structure, task_env_kwargs, task_of

__all__ = [
    "ALGOS",
    "algo_class",
    "train",
    "planned_timesteps",
    "TrainResult",
    "LatestCheckpoint",
    "BestPolicyCallback",
    "CONFIG_FILE",
    "MODEL_FILE",
]

ALGOS = ("ppo", "sac", "td3", "recurrentppo")
CONFIG_FILE = "config.yml"
MODEL_FILE = "model.zip"


def algo_class(algo: str) -> type[BaseAlgorithm]:
    """The SB3 (or sb3-contrib) class of an algorithm name."""
    a = algo.lower()
    if a == "recurrentppo":
        from sb3_contrib import RecurrentPPO

        return RecurrentPPO
    import stable_baselines3 as sb3

    classes = {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3}
    if a not in classes:
        raise InputError(f"unknown algorithm {algo!r}; choose from {', '.join(ALGOS)}")
    return classes[a]


class LatestCheckpoint(BaseCallback):
    """Saves the model to ``dir/latest.zip`` (with the replay buffer of off-policy algorithms and the
    reward normalisation) every ``every`` environment steps, overwriting the previous checkpoint
    (what ``resume`` needs)."""

    def __init__(self, directory: Path, every: int) -> None:
        super().__init__()
        self.dir, self.every, self._last = Path(directory), int(every), 0

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last >= self.every:
            self.save()
        return True

    def save(self) -> None:
        self._last = self.num_timesteps
        self.dir.mkdir(parents=True, exist_ok=True)
        self.model.save(self.dir / "latest.zip")
        if isinstance(self.model, OffPolicyAlgorithm):
            self.model.save_replay_buffer(self.dir / "latest_replay_buffer.pkl")
        vec_normalize = self.model.get_vec_normalize_env()
        if vec_normalize is not None:  # running reward statistics
            vec_normalize.save(self.dir / "latest_vecnormalize.pkl")


@dataclass
class TrainResult:
    """Outcome of :func:`train`: the model, its files and the wall time.

    Parameters
    ----------
    model : BaseAlgorithm
        The trained SB3 model.
    out : Path
        The run directory.
    model_path : Path
        ``model.zip``.
    policy_path : Path or None
        The exported ``policy.npz`` (None for RecurrentPPO or ``export=False``).
    wall_time : float
        Training time (s).
    timesteps : int
        Environment steps trained in all.
    """

    model: BaseAlgorithm
    out: Path
    model_path: Path
    policy_path: Path | None
    wall_time: float
    timesteps: int


def _settings(
    env_id: str,
    algo: str,
    obs: str | None,
    timesteps: int | None,
    n_envs: int | None,
    hyperparams: str | Path | None,
    overrides: dict[str, Any] | None,
    allow_zero: bool = False,
) -> dict[str, Any]:
    task = task_of(env_id)
    hp = load_hyperparams(algo, env_id, hyperparams, fallback=base_env_id(env_id) if task is not None else None)
    if task is not None:  # the task's fixed options in place of a base entry's; the user's are checked
        from_base = hp["hyperparams_entry"] != env_id
        hp["env_kwargs"] = task_env_kwargs(task, dict(hp["env_kwargs"]), from_base_entry=from_base)
    hp = apply_overrides(hp, overrides or {})
    env_kwargs = dict(hp["env_kwargs"])
    if obs is not None:
        env_kwargs["observation"] = obs
    if task is not None:
        env_kwargs = task_env_kwargs(task, env_kwargs)
        check_task_structure(task, hp)
    if timesteps is not None:
        hp["n_timesteps"] = timesteps
    if n_envs is not None:
        hp["n_envs"] = n_envs
    hp["env_kwargs"] = env_kwargs
    for key, kind in _NUMERIC_KEYS.items():  # a value of the wrong type is named here, not deep in training
        if key in hp:
            _number(key, hp[key], kind)
    if not (_number("n_timesteps", hp.get("n_timesteps", 0), int) >= (0 if allow_zero else 1)):
        raise InputError(f"number of timesteps must be >= 1, got {hp.get('n_timesteps')!r}")
    hp["n_timesteps"] = int(hp["n_timesteps"])
    hp["n_envs"] = int(hp.get("n_envs", 1))
    return hp


#: hyperparameters that drillgym reads as numbers (int or float)
_NUMERIC_KEYS = {
    "n_timesteps": int,
    "n_envs": int,
    "frame_stack": int,
    "gamma": float,
    "nominal_fraction": float,
    "nominal_below": float,
}


def _number(key: str, value: Any, kind: type) -> int | float:
    """``value`` of hyperparameter ``key`` as ``kind``; InputError naming the key when it is not one."""
    try:
        if isinstance(value, bool) or (kind is int and isinstance(value, float) and not value.is_integer()):
            raise TypeError
        return kind(value)
    except (TypeError, ValueError):
        what = "an integer" if kind is int else "a number"
        raise InputError(f"hyperparameter {key!r} must be {what}, got {value!r}") from None


def planned_timesteps(
    env_id: str,
    algo: str,
    timesteps: int | None = None,
    hyperparams: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
) -> int:
    """Environment steps a run of these settings will train (``timesteps`` or the file's ``n_timesteps``)."""
    algo_class(algo)  # an unknown algorithm is named before its hyperparameter file is looked for
    return _settings(env_id, algo.lower(), None, timesteps, None, hyperparams, overrides, allow_zero=True)[
        "n_timesteps"
    ]


def _env(env_id: str, hp: dict[str, Any], n: int, seed: int, evaluation: bool = False):
    """The training VecEnv of the (merged) hyperparameters ``hp``; ``evaluation``: its frozen twin (no
    statistics updates, raw rewards) for :class:`BestPolicyCallback`."""
    venv = make_training_env(
        env_id,
        n,
        seed=seed,
        env_kwargs=hp["env_kwargs"],
        residual=hp.get("residual"),
        startup=hp.get("startup"),
        base=hp.get("base"),
        observer=hp.get("observer"),
        frame_stack=int(hp.get("frame_stack", 1)),
        normalize_reward=bool(hp.get("normalize_reward", False)),
        normalize_obs=bool(hp.get("normalize_obs", False)),
        gamma=float(hp.get("gamma", 0.99)),
        privileged=bool(hp.get("privileged_critic", False)),
        motor_integral=bool(hp.get("motor_integral", False)),
        command=hp.get("command_schedule"),
        population=hp.get("population"),
        nominal_fraction=float(hp.get("nominal_fraction", 0.0)),
        nominal_below=float(hp.get("nominal_below", 0.0)),
        identified=hp.get("identified"),
    )
    if evaluation and isinstance(venv, VecNormalize):
        venv.training, venv.norm_reward = False, False
    return venv


def _warn_short_run(cls: type, hp: dict[str, Any]) -> None:
    """Warn when the run ends before the algorithm starts learning (off-policy ``learning_starts``)."""
    import inspect

    starts = hp.get("learning_starts", inspect.signature(cls.__init__).parameters.get("learning_starts"))
    if isinstance(starts, inspect.Parameter):
        starts = starts.default
    if isinstance(starts, (int, float)) and hp["n_timesteps"] <= starts:
        warnings.warn(
            f"--timesteps {hp['n_timesteps']} is not above the algorithm's learning_starts ({int(starts)}): "
            f"the agent collects random steps only and never learns",
            UserWarning,
            stacklevel=3,
        )


#: the evaluation rigs' seeds start here above the training seed (disjoint from the training rigs')
EVAL_SEED_OFFSET = 100_000
#: seed offset of the rigs of a second DAgger stage (``distill.then``)
THEN_SEED_OFFSET = 200_000


class BestPolicyCallback(EvalCallback):
    """SB3's ``EvalCallback`` (deterministic episodes, ``evaluations.npz``, ``best_model.zip``) in the run
    directory, exporting the best model's ``policy.npz`` beside it (``out/best/``); ``eval_every`` in
    environment steps of all rigs together."""

    def __init__(
        self,
        eval_env,
        out: Path,
        config: dict[str, Any],
        *,
        eval_every: int,
        n_envs: int,
        n_episodes: int,
        export: bool = True,
    ) -> None:
        super().__init__(
            eval_env,
            n_eval_episodes=n_episodes,
            eval_freq=max(1, int(eval_every) // max(1, n_envs)),
            best_model_save_path=str(Path(out) / "best"),
            log_path=str(out),
            deterministic=True,
            warn=False,
        )
        self.config, self.export = config, export

    def _on_step(self) -> bool:
        best = self.best_mean_reward
        go_on = super()._on_step()
        if self.export and self.best_mean_reward > best:
            from .export import export_policy

            export_policy(self.model, Path(self.best_model_save_path) / "policy.npz", self.config)
        return go_on


#: ``policy_kwargs.activation_fn`` by name (YAML cannot name a torch class)
ACTIVATIONS = ("relu", "tanh", "elu")


def _algo_kwargs(hp: dict[str, Any], n_actions: int) -> dict[str, Any]:
    kw = algorithm_kwargs(hp)
    pk = kw.get("policy_kwargs")
    act = pk.get("activation_fn") if isinstance(pk, dict) else None
    if isinstance(act, str):
        import torch

        name = act.lower().removeprefix("nn.")
        if name not in ACTIVATIONS:
            raise InputError(f"policy_kwargs.activation_fn must be one of {', '.join(ACTIVATIONS)}, got {act!r}")
        cls = {"relu": torch.nn.ReLU, "tanh": torch.nn.Tanh, "elu": torch.nn.ELU}[name]
        kw["policy_kwargs"] = {**pk, "activation_fn": cls}
    noise_type, noise_std = hp.get("noise_type"), hp.get("noise_std", 0.1)
    if noise_type == "normal":
        kw["action_noise"] = NormalActionNoise(np.zeros(n_actions), noise_std * np.ones(n_actions))
    elif noise_type is not None:
        raise InputError(f"noise_type must be 'normal' or absent, got {noise_type!r}")
    return kw


def train(
    env_id: str,
    algo: str,
    out: str | Path,
    *,
    obs: str | None = None,
    timesteps: int | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    hyperparams: str | Path | None = None,
    overrides: dict[str, Any] | None = None,
    resume: bool = False,
    progress: bool = True,
    tensorboard: bool = True,
    checkpoint_every: int = 50_000,
    export: bool = True,
    verbose: int = 0,
    torch_threads: int | None = 1,
    command: str | None = None,
    eval_every: int = 0,
    eval_envs: int = 8,
    teacher: str | Path | None = None,
    distill_kwargs: dict[str, Any] | None = None,
    model: Any = None,
    trust: bool = False,
    init: str | Path | None = None,
) -> TrainResult:
    """Train ``algo`` on ``env_id`` and write the run into ``out`` (see the module docstring).

    Parameters
    ----------
    env_id : str
        Gymnasium id of the environment, e.g. ``"drillgym/Torsional-v0"``.
    algo : str
        Algorithm: ``"ppo"``, ``"sac"``, ``"td3"`` or ``"recurrentppo"``.
    out : str or path
        Run directory (created if missing).
    obs : str, optional
        Observation mode ('full', 'sensors', 'motor'); default the hyperparameter file's.
    timesteps : int, optional
        Environment steps (all rigs together); default the file's ``n_timesteps``.
    seed : int, optional
        Seed of the networks, the exploration and the env (rig i: seed + i).
    n_envs : int, optional
        Number of rigs stepped together; default the file's ``n_envs``.
    hyperparams : str or path, optional
        YAML file (rl-zoo3 layout) instead of ``agents/hyperparams/<algo>.yml``.
    overrides : dict, optional
        Entries replacing those of the file (e.g. ``{"learning_rate": 1e-3}``).
    resume : bool, optional
        Continue from ``out/checkpoints/latest.zip`` up to ``timesteps`` in total.
    progress : bool, optional
        Show SB3's progress bar.
    tensorboard : bool, optional
        Write TensorBoard logs into ``out/tb``.
    checkpoint_every : int, optional
        Environment steps between checkpoints ``out/checkpoints/latest.zip``.
    export : bool, optional
        Write the exported policy ``policy.npz`` (MLP policies; not for RecurrentPPO).
    verbose : int, optional
        SB3 verbosity (0: silent).
    torch_threads : int or None, optional
        Torch CPU threads (the rig PC and CI machines are small; None = torch's default).
    command : str, optional
        The command line that started the run, recorded in ``config.yml``.
    eval_every : int, optional
        Environment steps between evaluations (0 = none): ``eval_envs`` episodes of the deterministic policy on
        rigs seeded apart from the training's; the best mean reward's model is kept in ``out/best/``
        (``best_model.zip``, ``policy.npz``), the curve in ``out/evaluations.npz``.
    eval_envs : int, optional
        Episodes per evaluation (one rig each).
    teacher : str or path, optional
        An exported policy of the 'full' observation, 'flatness' or 'lqg-2enc' (:mod:`agents.teachers`): before the RL
        steps, its actions are distilled into this model's actor by DAgger (:mod:`agents.distill`,
        ``distill_kwargs`` over the hyperparameters' ``distill`` entry, whose ``teacher`` is the default);
        ``timesteps`` may then be 0 (distillation only).  The entry's ``then`` (a mapping of DAgger options)
        runs a second stage from the first's student with those options changed (fresh rigs and fresh aggregated
        data, e.g. another training population).
    distill_kwargs : dict, optional
        DAgger options (:func:`agents.distill.distill`) over the hyperparameters' ``distill`` entry.
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path): every training and evaluation rig
        runs its base parameters and effects (env option ``model``; on a task id the task's nominal model,
        :mod:`agents.benchmark_env`; with a ``population`` structure the nominal rig the plants are drawn
        around).  Refused beside env options ``params``, ``effects`` or ``effect_params``.  ``config.yml``
        records it (base parameters and effect records).
    trust : bool, optional
        Read a model file's effect files even when untrusted (:meth:`drillgym.Model.load`).
    init : str or path, optional
        Start from the weights of this run directory's ``model.zip`` (or that file) instead of a fresh network:
        the same algorithm, spaces and layers, else refused (:mod:`agents.finetune`); not with ``resume``.
        With ``model``: a policy adapted to that model's rig.  ``config.yml`` records it.

    Returns
    -------
    TrainResult
        The trained model, the paths of its files and the wall time (s).
    """
    import torch

    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    algo = algo.lower()
    cls = algo_class(algo)
    hp = _settings(env_id, algo, obs, timesteps, n_envs, hyperparams, overrides, allow_zero=True)
    recorded_hp = hp
    if model is not None:
        hp, recorded_hp = with_model(hp, model, trust)
    distill_kwargs = {**(hp.get("distill") or {}), **(distill_kwargs or {})}
    if teacher is None:
        teacher = distill_kwargs.pop("teacher", None)
    else:
        distill_kwargs.pop("teacher", None)
    if teacher is None and hp["n_timesteps"] < 1:
        raise InputError(f"number of timesteps must be >= 1 without a teacher, got {hp['n_timesteps']!r}")
    if teacher is not None and not resume:
        if (
            algo != "ppo"
            or hp.get("normalize_obs")
            or (int(hp.get("frame_stack", 1)) != 1 and hp.get("privileged_critic"))
        ):
            raise InputError(
                "a teacher is distilled into PPO without observation normalisation (nor frame stacking with the "
                "privileged critic)"
            )
    if init is not None and resume:
        raise InputError("init: a resumed run continues its own checkpoint; give init or resume, not both")
    if resume:
        check_resumed_model(Path(out) / CONFIG_FILE, recorded_hp)
    venv = _env(env_id, hp, hp["n_envs"], seed)
    config = {"env_id": env_id, "algo": algo, "seed": int(seed), "hyperparams": recorded_hp, "command": command}
    if init is not None:
        config["init"] = str(init)
    if teacher is not None:
        config["teacher"] = {"policy": str(teacher), **distill_kwargs}
    ckpt = out / "checkpoints" / "latest.zip"
    tb = str(out / "tb") if tensorboard else None
    if resume:
        if not ckpt.is_file():
            raise MissingFileError(f"cannot resume: no checkpoint {ckpt}")
        stats = ckpt.with_name("latest_vecnormalize.pkl")
        if isinstance(venv, VecNormalize) and stats.is_file():
            venv = VecNormalize.load(str(stats), venv.venv)
        model = cls.load(ckpt, env=venv, tensorboard_log=tb)
        rb = ckpt.with_name("latest_replay_buffer.pkl")
        if isinstance(model, OffPolicyAlgorithm) and rb.is_file():
            model.load_replay_buffer(rb)
    else:
        policy, kw = hp["policy"], _algo_kwargs(hp, venv.action_space.shape[0])
        if hp.get("privileged_critic"):
            if algo != "ppo" or policy != "MlpPolicy":
                raise InputError("privileged_critic needs PPO with the MlpPolicy")
            from .privileged import PRIVILEGED, PrivilegedCriticPolicy

            policy = PrivilegedCriticPolicy
            kw["policy_kwargs"] = {
                **kw.get("policy_kwargs", {}),
                "actor_dim": venv.observation_space.shape[0] - len(PRIVILEGED),
            }
        model = cls(policy, venv, seed=seed, tensorboard_log=tb, verbose=verbose, **kw)
        if init is not None:
            from .finetune import start_from

            start_from(model, init, venv)
    t_distill = time.perf_counter()
    if teacher is not None and not resume:
        from .distill import distill

        first = {k: v for k, v in distill_kwargs.items() if k != "then"}
        then = distill_kwargs.get("then")
        if then is not None and (not isinstance(then, dict) or "teacher" in then or "then" in then):
            # refused before the first stage's minutes of training, not after them
            raise InputError(
                f"distill.then must be a mapping of DAgger options (no teacher, no third stage), got {then!r}"
            )
        common = dict(
            privileged=bool(hp.get("privileged_critic")),
            motor_integral=bool(hp.get("motor_integral")),
            command=hp.get("command_schedule"),
            frame_stack=int(hp.get("frame_stack", 1)),
            log=print,
        )
        distill(model, env_id, hp["env_kwargs"], teacher, n_envs=hp["n_envs"], seed=seed, **common, **first)
        if then:  # a second DAgger stage from the first's student, with these options changed
            print(f"second DAgger stage: {then}")
            distill(
                model,
                env_id,
                hp["env_kwargs"],
                teacher,
                n_envs=hp["n_envs"],
                seed=seed + THEN_SEED_OFFSET,
                **common,
                **{**first, **then},
            )
    t_distill = time.perf_counter() - t_distill
    _warn_short_run(cls, hp)  # once every check passed: a refusal is one line, not a warning and a refusal
    # written once the environment, the model and the teacher took every option (the teacher's observation, the
    # distillation's options are checked as it starts): a refused run leaves OUT as it was
    out = create_directory(out)
    (out / CONFIG_FILE).write_text(yaml.safe_dump(config, sort_keys=False))
    remaining = hp["n_timesteps"] - (model.num_timesteps if resume else 0)
    cb = LatestCheckpoint(out / "checkpoints", checkpoint_every)
    callbacks: list[BaseCallback] = [cb]
    eval_env = None
    if eval_every:
        eval_env = _env(env_id, hp, eval_envs, seed + EVAL_SEED_OFFSET, evaluation=True)
        callbacks.append(
            BestPolicyCallback(
                eval_env,
                out,
                config,
                eval_every=eval_every,
                n_envs=hp["n_envs"],
                n_episodes=eval_envs,
                export=export and algo != "recurrentppo",
            )
        )
    t0 = time.perf_counter()
    if remaining > 0:
        model.learn(
            remaining,
            callback=CallbackList(callbacks),
            progress_bar=progress,
            reset_num_timesteps=not resume,
            tb_log_name=algo,
        )
    wall = time.perf_counter() - t0 + t_distill
    if getattr(cb, "model", None) is None:  # no RL steps (distillation only): learn() never bound the callback
        cb.init_callback(model)
    cb.save()
    if eval_env is not None:
        eval_env.close()
    model_path = out / MODEL_FILE
    model.save(model_path)
    policy_path = None
    if export and algo != "recurrentppo":
        from .export import export_policy

        policy_path = export_policy(model, out / "policy.npz", config)
    venv.close()
    return TrainResult(model, out, model_path, policy_path, wall, int(model.num_timesteps))
