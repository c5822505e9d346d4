"""The environments of the named benchmark tasks (:mod:`drillgym.envs.tasks`): the Gymnasium entry points.

The task ids are registered in :mod:`drillgym.envs` by entry-point string, pointing here: a population
task's training plants are drawn from the uncertainty set by
:func:`controllers.evaluation.population.sample_plants`, which the physics core does not import.

``model=`` (a :class:`drillgym.Model` or a model file's path) is the task's nominal model: a nominal task
runs it (its base parameters and effects); a population task draws its training plants AROUND it (the
uncertainty set's relative ranges scale the model's base parameters, the set's effect parameters are drawn
from their ranges, every other effect parameter of the model keeps the model's value; the env's model is the
model's effects followed by the set's effects it lacks).

    >>> env = gymnasium.make("drillgym/Nominal-Motor-v0", model="runs/identified/model.json")

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

__all__ = [
    "make_task_env",
    "make_task_vec",
    "train_plants",
    "eval_plants",
    "install_plants",
    "task_model",
    "plant_matrix",
]


@lru_cache(maxsize=8)
def _population(uncertainty: str, n: int, seed: int, params=None):
    from controllers.evaluation.population import sample_plants

    return sample_plants(n, seed, None if uncertainty == "default" else uncertainty, params=params)


def train_plants(task: BenchmarkTask, model=None):
    """The task's training plants (:class:`controllers.evaluation.population.PlantPopulation`), or None
    for a nominal task; with ``model`` (a :class:`drillgym.Model`) drawn around its base parameters."""
    p = task.plants
    params = None if model is None else model.params
    return _population(p.uncertainty, p.train_plants, p.train_seed, params) if p.population else None


def task_model(task: BenchmarkTask, model: Any):
    """The env's model of a task given ``model=``: the model itself on a nominal task; on a population task
    the model with the uncertainty set's effects it lacks appended (their values drawn per plant).

    Parameters
    ----------
    task : BenchmarkTask
        The task.
    model : drillgym.Model, str or path
        The nominal model, or its file (read without ``trust``).

    Returns
    -------
    drillgym.Model
        The model the task's env runs (a population task's plants replace its drawn parameters).
    """
    from drillgym.model import as_model

    m = as_model(model, who=f"task {task.id}: model")
    pop = train_plants(task, m)
    if pop is None:
        return m
    have = set(m.names)
    extra = [e for e in pop.composition.effects if e.name not in have]
    return m.replace(effects=tuple(m.composition.effects) + tuple(extra)) if extra else m


def plant_matrix(pop, composition, model) -> np.ndarray:
    """The plants of ``pop`` in the layout of ``composition`` (the env's model): the model's parameter vector
    with every parameter the population draws replaced by each plant's.

    Parameters
    ----------
    pop : controllers.evaluation.population.PlantPopulation
        The plants (drawn around ``model``'s base parameters).
    composition : Composition
        The env's composition; it holds every effect of the population.
    model : drillgym.Model
        The nominal model: the values of what the population does not draw.

    Returns
    -------
    numpy.ndarray
        (n_plants, n_params) parameter rows.
    """
    base = composition.vector(model.params, {k: v for k, v in model.values.items() if k in composition.param_names})
    out = np.repeat(base[None, :], pop.n, axis=0)
    for name in pop.composition.param_names:
        out[:, composition.param_index(name)] = pop.matrix[:, pop.composition.param_index(name)]
    return out


def eval_plants(task: BenchmarkTask):
    """The task's held-out plants (:class:`controllers.evaluation.population.PlantPopulation`), or None
    for a nominal task."""
    p = task.plants
    return _population(p.uncertainty, p.eval_plants, p.eval_seed) if p.population else None


def _options(task: BenchmarkTask, free: dict[str, Any], model=None) -> dict[str, Any]:
    opts = task.env_options(**free)
    if model is not None:
        opts["model"] = task_model(task, model)
        return opts
    pop = train_plants(task)
    if pop is not None:
        opts["effects"] = list(pop.composition.specs())
    return opts


def install_plants(batch, task: BenchmarkTask, model=None) -> None:
    """Draw every later episode's rig of an episode batch from the task's training plants (none: nominal).

    Parameters
    ----------
    batch : drillgym.envs.engine.EpisodeBatch
        The env's episodes.
    task : BenchmarkTask
        The task.
    model : drillgym.Model, str or path, optional
        The nominal model the plants are drawn around (see the module docstring); default the identified rig.
    """
    if model is not None:
        from drillgym.model import as_model

        m = as_model(model, who=f"task {task.id}: model")
        pop = train_plants(task, m)
        if pop is not None:
            batch.randomizer = PlantListRandomizer(plant_matrix(pop, batch.system.composition, m))
        return
    pop = train_plants(task)
    if pop is None:
        return
    if tuple(batch.system.composition.param_names) != tuple(pop.composition.param_names):
        raise InputError(
            f"task {task.id}: the env's model {batch.system.composition.label} does not match the plants' "
            f"{pop.composition.label}"
        )
    batch.randomizer = PlantListRandomizer(pop.matrix)


def make_task_env(task: str, render_mode: str | None = None, model: Any = None, **options: Any) -> DrillEnv:
    """One env of a named task (the entry point of ``gymnasium.make(task_id)``).

    Parameters
    ----------
    task : str
        The task id (:data:`drillgym.envs.tasks.TASKS`).
    render_mode : str, optional
        As :class:`drillgym.envs.DrillEnv`.
    model : drillgym.Model, str or path, optional
        The task's nominal model (see the module docstring): a nominal task runs it, a population task draws
        its training plants around it.  Default the identified rig.
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
    if model is not None:
        from drillgym.model import as_model

        model = as_model(model, who=f"task {t.id}: model")
    env = DrillEnv(render_mode=render_mode, **_options(t, options, model))
    install_plants(env.batch, t, model)
    return env


def make_task_vec(task: str, num_envs: int, model: Any = None, **options: Any) -> DrillVectorEnv:
    """``num_envs`` rigs of a named task in one batched core call per step (the vector entry point).

    Parameters
    ----------
    task : str
        The task id.
    num_envs : int
        Number of rigs (>= 1).
    model : drillgym.Model, str or path, optional
        The task's nominal model, as :func:`make_task_env`.
    **options
        Only :data:`drillgym.envs.tasks.FREE_OPTIONS` (``render_mode`` ``"rgb_array"`` or None), and
        ``autoreset_mode`` of :class:`drillgym.envs.DrillVectorEnv`.

    Returns
    -------
    DrillVectorEnv
        The vector env; on a population task each episode's rig is one of the task's training plants.
    """
    t = get_task(task)
    if model is not None:
        from drillgym.model import as_model

        model = as_model(model, who=f"task {t.id}: model")
    extra = {k: options.pop(k) for k in ("autoreset_mode",) if k in options}
    opts = _options(t, options, model)
    venv = DrillVectorEnv(num_envs, opts.pop("configuration"), **extra, **opts)
    install_plants(venv.batch, t, model)
    return venv


def plant_rows_equal(a: np.ndarray, b: np.ndarray) -> int:
    """Number of rows of ``a`` equal to some row of ``b`` (parameter vectors compared exactly)."""
    rows = {tuple(r) for r in np.asarray(b, dtype=float)}
    return sum(tuple(r) in rows for r in np.asarray(a, dtype=float))
