"""The jobs of a population scenario (``plants``): chunks of plants x every target as one batch.

The plants are drawn from an uncertainty set (:func:`.population.sample_plants`: a job gets the population's
size, seed and set, and draws its own chunk again) or written by the user (:mod:`.plants_file`: a job gets
the :class:`.plants_file.PlantSet` and the indices of a chunk of one composition).  Every controller is
built from the nominal base parameters (or its ``model``, or the model identified on its plant,
:func:`identify_population`) with its default encoder assumptions: the plants' encoders are not told.
An error names the plant it happened on (:func:`on_plant`).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping, Sequence
from concurrent.futures import Executor
from contextlib import contextmanager
from typing import Any

import numpy as np

from drillgym import RigParams, parse_configuration
from drillgym.errors import DrillgymError, InputError

from .jobs import build_controller, margin_columns, run_all
from .metrics import run_metrics
from .population import PlantPopulation, sample_plants
from .runner import run_closed_loop
from .scenarios import Scenario

__all__ = ["run_population_job", "plant_label", "on_plant", "identify_population", "identify_then_run"]


def _population(
    plants: Sequence[int], n: int, seed: int, uncertainty: Any, base: RigParams | None, plant_set: Any
) -> PlantPopulation:
    """The plants ``plants`` of the user's ``plant_set``, or of the population of ``n`` drawn with ``seed``."""
    if plant_set is not None:
        return plant_set.population(plants)
    return sample_plants(n, seed, uncertainty, base).subset(list(plants))


def _label(k: int, n: int, seed: int, columns: Mapping[str, float], plant_set: Any) -> str:
    return plant_set.label(k) if plant_set is not None else plant_label(k, n, seed, columns)


def run_population_job(
    controller: str,
    config: str,
    scenario: Scenario,
    targets: Sequence[float],
    base: RigParams,
    *,
    duration: float,
    window: float,
    seed: int,
    plants: Sequence[int],
    n_plants: int,
    uncertainty: Any,
    model: Any = None,
    identified: Mapping[int, Any] | None = None,
    plant_set: Any = None,
) -> list[dict]:
    """The plants ``plants`` x ``targets`` as one batch (one row per plant and target); the controller built
    from ``base`` (or ``model``; with ``identified``, plant index -> :class:`.identify.IdentifiedPlant`, one
    controller per plant on its identified model).  ``plant_set``: the user's plants
    (:class:`.plants_file.PlantSet`; ``plants`` of one composition), else the population of ``n_plants`` drawn
    with ``seed`` from ``uncertainty``."""
    pop = _population(plants, n_plants, seed, uncertainty, base, plant_set)
    if identified:  # one controller per plant, on that plant's identified model
        rows = []
        for i, k in enumerate(plants):
            try:
                with on_plant(_label(k, n_plants, seed, pop.columns[i], plant_set), identified=True):
                    one = _run_plants(
                        controller, config, scenario, targets, base, pop.subset([i]), duration, window, seed, [k],
                        identified[k].model,
                    )  # fmt: skip
            except InputError as exc:  # a model the controller refuses: one line naming the plant, the others go on
                warnings.warn(str(exc), stacklevel=2)
                continue
            rows += [{**r, **identified[k].columns()} for r in one]
        return rows
    if len(plants) == 1:
        with on_plant(_label(plants[0], n_plants, seed, pop.columns[0], plant_set)):
            return _run_plants(controller, config, scenario, targets, base, pop, duration, window, seed, plants, model)
    try:
        return _run_plants(controller, config, scenario, targets, base, pop, duration, window, seed, plants, model)
    except DrillgymError:  # which plant: each alone, the first that fails names itself
        for k in plants:
            run_population_job(
                controller, config, scenario, targets, base, duration=duration, window=window, seed=seed,
                plants=[k], n_plants=n_plants, uncertainty=uncertainty, model=model, plant_set=plant_set,
            )  # fmt: skip
        raise


def plant_label(k: int, n: int, seed: int, columns: Mapping[str, float]) -> str:
    """``plant 3 of 20 (seed 0: km 4.38, Jl 0.0395, ...)``: a plant of a population and the values it was drawn with."""
    values = ", ".join(f"{name} {_short(v)}" for name, v in columns.items())
    return f"plant {k} of {n} (seed {seed}: {values})"


def _short(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else f"{float(v):.3g}"


@contextmanager
def on_plant(label: str, *, identified: bool = False, doing: str = "") -> Iterator[None]:
    """Within the block, an error is re-raised (same kind) led by the plant it happened on (``label``:
    :func:`plant_label`, or :meth:`.plants_file.PlantSet.label`), what was being done (``doing``) and, with
    ``identified``, that the controller ran the model identified on that plant."""
    try:
        yield
    except DrillgymError as exc:
        message = " ".join(str(exc).split())
        if message.startswith("plant "):  # named already (an inner job)
            raise
        where = label + (f", {doing}" if doing else "")
        if identified:
            where += ", its controller built on the model identified on that plant"
        text = f"{where}: {message}"
        try:
            new = type(exc)(text)
        except Exception:  # a kind with its own constructor
            new = InputError(text)
        raise new from exc


def _run_plants(
    controller: str,
    config: str,
    scenario: Scenario,
    targets: Sequence[float],
    base: RigParams,
    pop: PlantPopulation,
    duration: float,
    window: float,
    seed: int,
    plants: Sequence[int],
    model: Any,
) -> list[dict]:
    """The plants ``pop`` (indices ``plants``) x ``targets`` as one batch."""
    tg = np.asarray(targets, dtype=float)
    m = tg.size
    idx = np.repeat(np.arange(pop.n), m)  # plant of each trajectory
    ref = np.tile(tg, pop.n)
    ctrl, label = build_controller(controller, config, ref, base, model)
    run = run_closed_loop(
        ctrl,
        config,
        ref,
        duration,
        params=pop.matrix[idx],
        counts_per_rev=pop.counts_per_rev[idx],
        angle_noise=pop.angle_noise[idx],
        seed=int(seed) * 100_003 + int(plants[0]),
        effects=pop.composition,
    )  # measurement noise: its own stream per chunk of plants
    met = run_metrics(run, window, base)
    rows = []
    for i in range(ref.size):
        k = int(idx[i])
        row = {
            "controller": controller,
            "config": parse_configuration(config).label,
            "scenario": scenario.name,
            "plant": int(plants[k]),
            **({"plant_name": pop.names[k], "effects": pop.composition.label} if pop.names else {}),
            **pop.columns[k],
            "model": label,
            **margin_columns(ctrl, float(ref[i])),
            "omega_ref": float(ref[i]),
            "control_dt": float(ctrl.dt),
        }
        row.update({key: (bool(v[i]) if v.dtype == bool else float(v[i])) for key, v in met.items()})
        rows.append(row)
    return rows


def identify_population(
    n: int,
    seed: int,
    uncertainty: Any,
    params: RigParams | None,
    options: Any,
    config: str,
    executor: Executor | None = None,
    workers: int = 1,
    progress: bool = True,
    plant_set: Any = None,
    indices: Sequence[int] | None = None,
) -> dict[int, Any]:
    """Plant index -> :class:`.identify.IdentifiedPlant` of each plant of the population (one excitation run,
    diagnose and identify per plant; in ``executor`` or a pool of ``workers`` processes); ``plant_set``: the
    user's plants (:class:`.plants_file.PlantSet`), else the ``n`` drawn with ``seed`` from ``uncertainty``;
    ``indices``: only these plants of the ``n`` (default all)."""
    ks = list(range(n)) if indices is None else [int(k) for k in indices]
    args = [identify_arguments(k, n, seed, uncertainty, params, options, config, plant_set) for k in ks]
    found = run_all([(_identify_one, a, {}) for a in args], executor, workers, "identify", "plant", progress)
    return dict(zip(ks, found, strict=True))


def identify_arguments(
    k: int, n: int, seed: int, uncertainty: Any, params: RigParams | None, options: Any, config: str, plant_set: Any
) -> tuple:
    """The arguments of one plant's identification (:func:`identify_population`'s, for plant ``k``)."""
    from .identify import ExcitationOptions

    opts = options if isinstance(options, ExcitationOptions) else ExcitationOptions()
    return (int(k), n, seed, uncertainty, params, opts, config, plant_set)


def identify_then_run(identify: tuple, calls: Sequence[tuple]) -> list[dict]:
    """One plant's task: identify it (``identify``: :func:`identify_arguments`), then run each ``(function, args,
    kwargs)`` of ``calls`` (its jobs, :func:`run_population_job` through the harness) with the controllers built on
    that identification (``identified={k: ...}``).  One task per plant, not a phase of identifications and then
    one of control, leaves no core waiting for the slowest identification before the runs start."""
    found = _identify_one(*identify)
    return [row for fn, a, kw in calls for row in fn(*a, **{**kw, "identified": {identify[0]: found}})]


def _identify_one(
    k: int, n: int, seed: int, uncertainty: Any, params: RigParams | None, opts: Any, config: str, plant_set: Any
):
    from .identify import excitation_recording, identify_plant

    pop = _population([k], n, seed, uncertainty, params, plant_set)
    with on_plant(_label(k, n, seed, pop.columns[0], plant_set), doing="identifying it"):
        rec = excitation_recording(
            pop.matrix[0], pop.composition, pop.counts_per_rev[0], pop.angle_noise[0], int(seed) * 100_003 + k, opts,
            parse_configuration(config).label,
        )  # fmt: skip
        return identify_plant(rec, [n for n in pop.columns[0] if n not in ("counts_per_rev", "angle_noise")], opts)
