"""Trials on Ray Tune: several seeds of one training, or a hyperparameter grid, on a Ray cluster.

:func:`run_trials` runs ``fn(config)`` once per config as a Ray Tune trial (``cpus_per_trial`` CPUs each,
as many at once as the cluster holds) and returns the results in the order of ``configs``.  A trial that
fails (its worker died or ``fn`` raised) is restarted up to ``retries`` times (Tune's
``FailureConfig``); one that still fails is raised as :class:`drillgym.parallel.TaskFailed` naming its
config.  Tune's progress table is printed while the trials run (``progress=False``: none).

    >>> rows = run_trials(train_one_seed, [dict(kw, seed=s) for s in range(5)], ray="auto")
    >>> rows = run_trials(train_one, [dict(kw, overrides={"learning_rate": lr}) for lr in (1e-4, 3e-4, 1e-3)])

``fn`` and the configs travel to the workers by pickle (a module function of an installed package, e.g.
``agents.seeds._train_one``); each trial writes its own files, so on a cluster of several machines
its output directory must be on storage every machine sees (NFS) or be collected afterwards.  Tune's
bookkeeping goes to ``storage`` (default ``~/ray_results``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .errors import InputError
from .parallel import TaskFailed, connect_ray

__all__ = ["run_trials"]

_RESULT = "drillgym_result"


def _trainable(fn: Callable[[Any], Any], configs: Sequence[Any]) -> Callable[[dict], None]:
    cwd = os.getcwd()

    def trial(tune_config: dict) -> None:
        from ray import tune

        if os.path.isdir(cwd):  # Tune starts a trial in its own log directory: relative paths mean the driver's
            os.chdir(cwd)

        index = tune_config["trial"]["index"]
        result = fn(configs[index])
        tune.report({_RESULT: result, "done_index": index})

    return trial


def _label(config: Any, index: int) -> str:
    """What Tune's progress table shows for a trial: its seed when the config has one."""
    if isinstance(config, dict) and "seed" in config:
        return f"seed={config['seed']}"
    return f"config {index}"


def run_trials(
    fn: Callable[[Any], Any],
    configs: Sequence[Any],
    *,
    ray: str | None = "local",
    cpus_per_trial: float = 1.0,
    workers: int | None = None,
    retries: int = 1,
    name: str = "drillgym",
    storage: str | Path | None = None,
    progress: bool = True,
) -> list:
    """``[fn(c) for c in configs]`` as Ray Tune trials; see the module docstring.

    Parameters
    ----------
    fn : callable
        ``fn(config)``, run once per config in a trial; its results are returned in config order.
    configs : sequence
        The configs, at least one.
    ray : str or None, optional
        ``"local"`` (default), ``"auto"`` or an address (:func:`drillgym.parallel.connect_ray`);
        None: already connected.
    cpus_per_trial : float, optional
        CPUs Ray reserves per trial.  Default 1.
    workers : int, optional
        CPUs of a ``"local"`` instance; default all.
    retries : int, optional
        Times a failed trial is retried.  Default 1.
    name : str, optional
        Name of the Tune experiment.
    storage : str or path, optional
        Directory of Tune's results; default Ray's.
    progress : bool, optional
        Show Tune's progress.

    Returns
    -------
    list
        ``fn(c)`` for each config, in order.

    Raises
    ------
    InputError
        No config.
    """
    from ray import tune
    from ray.tune import FailureConfig, RunConfig, TuneConfig

    configs = list(configs)
    if not configs:
        raise InputError("run_trials needs at least one config")
    started = connect_ray(ray, num_cpus=workers) if ray is not None else False
    try:
        storage_path = str(Path(storage).resolve()) if storage is not None else None
        tuner = tune.Tuner(
            tune.with_resources(_trainable(fn, configs), {"cpu": cpus_per_trial}),
            param_space={
                "trial": tune.grid_search([{"index": i, "label": _label(c, i)} for i, c in enumerate(configs)])
            },
            tune_config=TuneConfig(reuse_actors=False),
            run_config=RunConfig(
                name=name,
                storage_path=storage_path,
                verbose=1 if progress else 0,
                failure_config=FailureConfig(max_failures=int(retries)),
            ),
        )
        grid = tuner.fit()
        out: list = [None] * len(configs)
        done = [False] * len(configs)
        for res in grid:
            if res.error is None and res.metrics and _RESULT in res.metrics:
                i = int(res.config["trial"]["index"])
                out[i], done[i] = res.metrics[_RESULT], True
        for res in grid:
            i = int(res.config["trial"]["index"])
            if not done[i]:
                err = res.error if res.error is not None else "it reported no result"
                cause = getattr(err, "cause", None) or err
                raise TaskFailed(fn, (configs[i],), {}, cause, attempts=int(retries) + 1)
        return out
    finally:
        if started:
            import ray as ray_module

            ray_module.shutdown()
