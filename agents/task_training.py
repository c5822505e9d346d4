"""Training on a named benchmark task (:mod:`drillgym.envs.tasks`): ``drillgym train --env TASK_ID``.

A task fixes the rig configuration, the sensors (the env's observation), the target range, the episode length
and the plants; a training run on it builds the task's base env (``drillgym/Torsional-v0`` or
``drillgym/Coupled-v0``) with exactly those options, and on a population task draws every episode's rig from
the task's fixed training list (:func:`agents.benchmark_env.train_plants`), never from the held-out plants.

Hyperparameters come from the file's entry for the task id or, when it has none, from its entry for the base
env with the task's fixed options in place of the entry's own (the entry's per-episode randomisation is dropped:
the task's plants are its randomisation).  What the user sets explicitly (``--set env_kwargs.NAME=...``,
``--obs``, ``--add-effect``, a ``population`` structure) may change only :data:`drillgym.envs.tasks.FREE_OPTIONS`;
anything else the task fixes is refused in one line naming it.

    drillgym train --env drillgym/Population-Motor-v0 --algo ppo --seed 1 --out runs/pop_motor_s1
"""

from __future__ import annotations

import math
from typing import Any

from drillgym.envs import ENV_IDS
from drillgym.envs.tasks import FREE_OPTIONS, TASKS, BenchmarkTask, get_task
from drillgym.errors import InputError

__all__ = [
    "is_task",
    "task_of",
    "base_env_id",
    "configuration_of",
    "hyperparameter_entry",
    "task_env_kwargs",
    "check_task_structure",
    "install_task_plants",
    "task_model_options",
]

#: env options of a base env's hyperparameter entry that a task replaces by its plants (dropped, not refused)
RANDOMISATION_KEYS = ("randomize", "randomize_names")
#: env options a training structure sets itself (the action's scaling follows the residual structure)
STRUCTURE_OPTIONS = ("normalize_action",)
#: drillgym training structures that draw plants of their own: a task's plants are fixed
PLANT_STRUCTURES = ("population", "nominal_fraction", "nominal_below")


def is_task(env_id: str) -> bool:
    """Whether ``env_id`` is a registered task id (``drillgym/Population-Motor-v0``, ...)."""
    return env_id in TASKS


def task_of(env_id: str) -> BenchmarkTask | None:
    """The task of a task id, None for a free env id (``drillgym/Torsional-v0``)."""
    return get_task(env_id) if is_task(env_id) else None


def base_env_id(env_id: str) -> str:
    """The free env id a task is built on (the id itself for a free env).

    Raises
    ------
    InputError
        Neither a drillgym env id nor a task id.
    """
    task = task_of(env_id)
    if task is not None:
        return next(k for k, v in ENV_IDS.items() if v == task.config)
    if env_id not in ENV_IDS:
        raise InputError(
            f"unknown drillgym environment {env_id!r}; expected one of {', '.join(ENV_IDS)} or a task "
            f"({', '.join(TASKS)})"
        )
    return env_id


def configuration_of(env_id: str) -> str:
    """The rig configuration (``torsional``, ``lateral``, ``coupled``) of an env or task id."""
    return ENV_IDS[base_env_id(env_id)]


def hyperparameter_entry(env_id: str, entries: set[str] | list[str]) -> str:
    """The hyperparameter file's entry a run on ``env_id`` reads: its own, or (a task without one) its base
    env's."""
    if env_id in entries or not is_task(env_id):
        return env_id
    return base_env_id(env_id)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-12, abs_tol=0.0)
    return a == b


def task_env_kwargs(task: BenchmarkTask, env_kwargs: dict[str, Any], from_base_entry: bool = False) -> dict[str, Any]:
    """The env options of a training run on a task: the task's fixed ones and the free ones given.

    Parameters
    ----------
    task : BenchmarkTask
        The task.
    env_kwargs : dict
        The run's env options (hyperparameter file and ``--set``).
    from_base_entry : bool, optional
        The options come from the base env's entry of the file (not the task's, not the user's): a fixed option
        of another value is replaced by the task's, and the entry's randomisation dropped, instead of refused.

    Returns
    -------
    dict
        Options of the base env (without ``configuration``).

    Raises
    ------
    InputError
        An option the task fixes, set to another value (naming the option, both values and the free options).
    """
    fixed = task.env_options()
    fixed.pop("configuration")
    free: dict[str, Any] = {}
    for key, value in env_kwargs.items():
        if key in FREE_OPTIONS or key in STRUCTURE_OPTIONS:
            free[key] = value
        elif key in fixed and _same(value, fixed[key]):
            continue
        elif not from_base_entry:
            shown = f" ({fixed[key]!r})" if key in fixed else ""
            raise InputError(
                f"task {task.id} fixes env option {key!r}{shown}; the run sets {value!r}. A task accepts only "
                f"{', '.join(FREE_OPTIONS)} (train on {base_env_id(task.id)} for free options)"
            )
    return {**fixed, **free}


def check_task_structure(task: BenchmarkTask, hp: dict[str, Any]) -> None:
    """Refuse a training structure that draws plants of its own on a task (its plants are fixed).

    Raises
    ------
    InputError
        ``population``, ``nominal_fraction`` or ``nominal_below`` set (also under ``distill``).
    """
    for where, section in (("", hp), ("distill.", hp.get("distill") or {})):
        for key in PLANT_STRUCTURES:
            value = section.get(key)
            if value not in (None, 0, 0.0):
                raise InputError(
                    f"task {task.id} fixes its plants; the hyperparameter {where}{key} ({value!r}) draws others "
                    f"(train on {base_env_id(task.id)} for a population of your own)"
                )


def install_task_plants(venv, task: BenchmarkTask, model: Any = None) -> None:
    """Draw every later episode's rig of a training VecEnv from the task's training plants (population tasks).

    Parameters
    ----------
    venv : stable_baselines3.common.vec_env.VecEnv
        A VecEnv built on :func:`drillgym.envs.sb3.make_sb3_vec` with :func:`task_env_kwargs` options (or a
        wrapper of one).
    task : BenchmarkTask
        The task.
    model : drillgym.Model, optional
        The task's nominal model the plants are drawn around (:mod:`agents.benchmark_env`).
    """
    from .batch import episode_batch
    from .benchmark_env import install_plants

    install_plants(episode_batch(venv), task, model)


def task_model_options(task: BenchmarkTask, model: Any = None) -> dict[str, Any]:
    """The env options that put a task's plant model in the env: a population task's effects (empty for a
    nominal one) or, with ``model`` (a :class:`drillgym.Model`), ``model=`` the task's nominal model
    (:func:`agents.benchmark_env.task_model`)."""
    from .benchmark_env import task_model, train_plants

    if model is not None:
        return {"model": task_model(task, model)}
    pop = train_plants(task)
    return {"effects": list(pop.composition.specs())} if pop is not None else {}
