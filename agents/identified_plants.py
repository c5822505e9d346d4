"""The identification of a task's plants: each plant's excitation run and :func:`drillgym.identify`, kept in a folder.

The identified tasks (``drillgym/...-Identified-v0``) give a policy the model the lab's identify-then-control
builds for its rig: the held-out plants' models when the policy is scored (:mod:`.benchmark`), the training
plants' models when a recipe trains on bases built on them (:mod:`.plantwise_residual`).  Both take the route of
``drillgym evaluate --identify`` (:func:`controllers.evaluation.population_jobs.identify_population`), and both
are kept as ``plant_<k>/model.json`` and ``identification.json``
(:func:`controllers.evaluation.identify.save_identified`), so a folder identified once serves every later policy
and seed.

    >>> from agents.identified_plants import identified_plants
    >>> models = identified_plants(get_task("Population-Motor-Identified-v0"), "train", 32, "runs/identified/train")
"""

from __future__ import annotations

from pathlib import Path

from drillgym.envs.tasks import BenchmarkTask
from drillgym.errors import InputError

__all__ = ["SPLITS", "identified_plants"]

#: which list of a task's plants: the held-out list (scored) or the training list
SPLITS = ("held-out", "train")


def identified_plants(
    task: BenchmarkTask,
    split: str,
    plants: int,
    folder: str | Path | None = None,
    workers: int = 1,
    progress: bool = False,
) -> dict:
    """Plant index -> :class:`controllers.evaluation.identify.IdentifiedPlant` of the first ``plants`` plants of
    one of the task's lists.

    Parameters
    ----------
    task : BenchmarkTask
        A population task.
    split : {"held-out", "train"}
        The held-out list (seed ``eval_seed``) or the training list (seed ``train_seed``).
    plants : int
        How many of the list's first plants (1 .. the list's length).
    folder : str or path, optional
        Where the identifications are kept: the plants it holds are read back, the others identified and
        written there.  Default: identified in memory, nothing kept.
    workers : int, optional
        Processes of the identification.
    progress : bool, optional
        Show a progress bar.

    Returns
    -------
    dict of int to IdentifiedPlant

    Raises
    ------
    InputError
        A nominal task, an unknown split or a number of plants outside the list.
    """
    from controllers.evaluation.identify import load_identified, save_identified
    from controllers.evaluation.population_jobs import identify_population

    p = task.plants
    if not p.population:
        raise InputError(f"task {task.id} runs the identified rig only: it has no plants to identify")
    if split not in SPLITS:
        raise InputError(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
    seed, listed = (p.eval_seed, p.eval_plants) if split == "held-out" else (p.train_seed, p.train_plants)
    if isinstance(plants, bool) or not isinstance(plants, int) or not (1 <= plants <= listed):
        raise InputError(f"plants must be in 1..{listed} (the {split} list of {task.id}), got {plants!r}")
    found = load_identified(folder, plants) if folder is not None else {}
    todo = [k for k in range(plants) if k not in found]
    unc = None if p.uncertainty == "default" else p.uncertainty
    step = len(todo) if folder is None else 2 * max(int(workers), 1)  # written as they come: an interrupted run
    for i in range(0, len(todo), max(step, 1)):  # keeps the plants it finished
        new = identify_population(
            listed, seed, unc, None, True, task.config, None, workers, progress, indices=todo[i : i + step]
        )
        if folder is not None:
            save_identified(new, folder)
        found.update(new)
    return dict(sorted(found.items()))
