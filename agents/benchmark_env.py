"""The environments of the named benchmark tasks (:mod:`drillgym.envs.tasks`): the Gymnasium entry points.

The task ids are registered in :mod:`drillgym.envs` by entry-point string, pointing here: a population
task's training plants are drawn from the uncertainty set by
:func:`controllers.evaluation.population.sample_plants`, which the physics core does not import.

    >>> import gymnasium, drillgym
    >>> env = gymnasium.make("drillgym/Population-TwoEncoder-v0")
    >>> venv = gymnasium.make_vec("drillgym/Population-Motor-v0", num_envs=64, vectorization_mode="vector_entry_point")
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from drillgym.envs import DrillEnv, DrillVectorEnv
from drillgym.envs.tasks import BenchmarkTask, PlantListRandomizer, get_task
from drillgym.errors import InputError

__all__ = ["make_task_env", "make_task_vec", "train_plants", "eval_plants", "install_plants"]


@lru_cache(maxsize=8)
def _population(uncertainty: str, n: int, seed: int):
    from controllers.evaluation.population import sample_plants

    return sample_plants(n, seed, None if uncertainty == "default" else uncertainty)


def train_plants(task: BenchmarkTask):
    """The task's training plants (:class:`controllers.evaluation.population.PlantPopulation`), or None
    for a nominal task."""
    p = task.plants
    return _population(p.uncertainty, p.train_plants, p.train_seed) if p.population else None


def eval_plants(task: BenchmarkTask):
    """The task's held-out plants (:class:`controllers.evaluation.population.PlantPopulation`), or None
    for a nominal task."""
    p = task.plants
    return _population(p.uncertainty, p.eval_plants, p.eval_seed) if p.population else None


def _options(task: BenchmarkTask, free: dict[str, Any]) -> dict[str, Any]:
    opts = task.env_options(**free)
    pop = train_plants(task)
    if pop is not None:
        opts["effects"] = list(pop.composition.specs())
    return opts


def install_plants(batch, task: BenchmarkTask) -> None:
    """Draw every later episode's rig of an episode batch from the task's training plants (none: nominal)."""
    pop = train_plants(task)
    if pop is None:
        return
    if tuple(batch.system.composition.param_names) != tuple(pop.composition.param_names):
        raise InputError(
            f"task {task.id}: the env's model {batch.system.composition.label} does not match the plants' "
            f"{pop.composition.label}"
        )
    batch.randomizer = PlantListRandomizer(pop.matrix)


def make_task_env(task: str, render_mode: str | None = None, **options: Any) -> DrillEnv:
    """One env of a named task (the entry point of ``gymnasium.make(task_id)``).

    Parameters
    ----------
    task : str
        The task id (:data:`drillgym.envs.tasks.TASKS`).
    render_mode : str, optional
        As :class:`drillgym.envs.DrillEnv`.
    **options
        Only :data:`drillgym.envs.tasks.FREE_OPTIONS`; the task fixes every other option.

    Returns
    -------
    DrillEnv
        The env; on a population task each episode's rig is one of the task's training plants.

    Raises
    ------
    InputError
        An unknown task or an option the task fixes.
    """
    t = get_task(task)
    env = DrillEnv(render_mode=render_mode, **_options(t, options))
    install_plants(env.batch, t)
    return env


def make_task_vec(task: str, num_envs: int, **options: Any) -> DrillVectorEnv:
    """``num_envs`` rigs of a named task in one batched core call per step (the vector entry point).

    Parameters
    ----------
    task : str
        The task id.
    num_envs : int
        Number of rigs (>= 1).
    **options
        Only :data:`drillgym.envs.tasks.FREE_OPTIONS` (``render_mode`` ``"rgb_array"`` or None), and
        ``autoreset_mode`` of :class:`drillgym.envs.DrillVectorEnv`.

    Returns
    -------
    DrillVectorEnv
        The vector env; on a population task each episode's rig is one of the task's training plants.
    """
    t = get_task(task)
    extra = {k: options.pop(k) for k in ("autoreset_mode",) if k in options}
    opts = _options(t, options)
    venv = DrillVectorEnv(num_envs, opts.pop("configuration"), **extra, **opts)
    install_plants(venv.batch, t)
    return venv


def plant_rows_equal(a: np.ndarray, b: np.ndarray) -> int:
    """Number of rows of ``a`` equal to some row of ``b`` (parameter vectors compared exactly)."""
    rows = {tuple(r) for r in np.asarray(b, dtype=float)}
    return sum(tuple(r) in rows for r in np.asarray(a, dtype=float))
