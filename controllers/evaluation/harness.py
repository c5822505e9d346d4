"""The evaluation harness: controllers x configurations x scenarios x target speeds, in parallel.

One job = one controller, one configuration, one scenario, all target speeds
as one batch of the core's simulator (:func:`.runner.run_closed_loop`).  The plant may run
hidden effects (``effects``/``effect_params``, :mod:`drillgym.effects`): the controllers are
built from the nominal base parameters and never know them, or from a ``model`` of their own
(a :class:`drillgym.Model`, e.g. an identified model file): ``observer``, ``lqg`` and
``lqg-2enc`` run its effects, the others its base parameters (the rows' ``model`` column says which).  Jobs
run in a ``concurrent.futures`` executor (processes by default), with a tqdm
progress bar.  Results are rows (dicts) with the metrics of :mod:`.metrics`.  A population of plants
(drawn, or listed in a plants file: ``plants_file=``) runs in the jobs of :mod:`.population_jobs`.

    >>> from controllers.evaluation import evaluate
    >>> rows = evaluate(["baseline", "observer"], ["torsional"], ["rest"], targets=[2.0, 3.0])
    >>> rows = evaluate(["observer"], ["torsional"], ["rest"], targets=[2.0], effects=["input_delay"],
    ...                 effect_params={"delay": 0.03})          # a plant with a hidden delay
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor
from typing import Any

import numpy as np

from drillgym import RigParams, parse_configuration
from drillgym.effects import compose
from drillgym.errors import InputError

from .jobs import build_controller, margin_columns, run_all
from .metrics import run_metrics
from .plants_file import PlantSet, load_plants
from .population import UncertaintySet, load_uncertainty, sample_plants
from .population_jobs import identify_arguments, identify_then_run, run_population_job
from .runner import run_closed_loop
from .scenarios import DEFAULT_TARGETS, SCENARIOS, Scenario, cycle_states, plant_params

__all__ = ["evaluate", "run_job", "short_run_warnings", "DEFAULT_DURATION", "DEFAULT_WINDOW"]

DEFAULT_DURATION = 60.0  # s per run
DEFAULT_WINDOW = 20.0  # s of steady state at the end


def run_job(
    controller: str,
    config: str,
    scenario: Scenario,
    targets: Sequence[float],
    *,
    duration: float = DEFAULT_DURATION,
    window: float = DEFAULT_WINDOW,
    params: dict | None = None,
    u_fold: float | None = None,
    seed: int = 0,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
    plants: Sequence[int] = (),
    n_plants: int = 0,
    uncertainty: Any = None,
    model: Any = None,
    identified: Mapping[int, Any] | None = None,
    plant_set: PlantSet | None = None,
) -> list[dict]:
    """Run one controller in one configuration and scenario for every target; one row per target.

    ``params``: nominal base parameters (dict; the controller's model and the plant's base);
    ``effects``/``effect_params``: hidden effects of the plant only (specs, classes or a Composition).
    A population scenario runs the plants ``plants`` (indices) of the population of ``n_plants`` drawn
    with ``seed`` from ``uncertainty`` (:mod:`.population`), or of the user's ``plant_set``
    (:mod:`.plants_file`, plants of one composition): one row per (plant, target).  ``model``: the
    controller's own model (a :class:`drillgym.Model`; default ``params`` without effects);
    ``identified``: plant index -> :class:`.identify.IdentifiedPlant`, each plant's controller built on its own
    identified model."""
    base = RigParams.from_dict(params) if params else RigParams()
    if scenario.population:
        return run_population_job(
            controller,
            config,
            scenario,
            targets,
            base,
            duration=duration,
            window=window,
            seed=seed,
            plants=plants,
            n_plants=n_plants,
            uncertainty=uncertainty,
            model=model,
            identified=identified,
            plant_set=plant_set,
        )
    comp, values = compose(effects, effect_params)
    plant = plant_params(scenario, base)
    tg = np.asarray(targets, dtype=float)
    x0 = None
    if scenario.start == "cycle":
        if u_fold is None:
            from ..baseline import stick_slip_region

            u_fold = stick_slip_region(config, base).u_fold
        x0 = cycle_states(config, tg, plant, u_fold, effects=comp, effect_params=values)
    elif scenario.start != "rest":
        raise InputError(f"scenario start must be 'rest' or 'cycle', got {scenario.start!r}")
    from ..registry import split_period

    kw = {}
    if split_period(controller)[0] in ("observer", "observer-robust", "lqg"):
        kw = {"counts_per_rev": scenario.counts_per_rev, "angle_noise": scenario.angle_noise}
    ctrl, label = build_controller(controller, config, tg, base, model, **kw)  # never the hidden effects
    run = run_closed_loop(
        ctrl,
        config,
        tg,
        duration,
        params=plant,
        x0=x0,
        counts_per_rev=scenario.counts_per_rev,
        angle_noise=scenario.angle_noise,
        seed=seed,
        effects=comp,
        effect_params=values,
    )
    met = run_metrics(run, window, base)
    rows = []
    for i, w in enumerate(tg):
        row = {
            "controller": controller,
            "config": parse_configuration(config).label,
            "scenario": scenario.name,
            "plant": comp.label,
            "model": label,
            **margin_columns(ctrl, float(w)),
            "omega_ref": float(w),
            "control_dt": float(ctrl.dt),
        }
        row.update({k: (bool(v[i]) if v.dtype == bool else float(v[i])) for k, v in met.items()})
        rows.append(row)
    return rows


def short_run_warnings(
    controllers: Sequence[str],
    config: str,
    targets: Sequence[float],
    duration: float,
    window: float,
    params: RigParams | None = None,
) -> list[str]:
    """One line per controller whose approach to a target (its :meth:`Controller.approach_time`) ends
    after the steady window starts (``duration - window`` s): that run judges a transient."""
    from .. import make

    out = []
    tg = np.asarray(targets, dtype=float)
    for c in controllers:
        if c.startswith("agent:"):
            continue
        need = np.asarray(make(c, config=config, omega_ref=tg, params=params or RigParams()).approach_time(tg))
        late = need > duration - window
        if np.any(late):
            out.append(
                f"{c}: the approach to {', '.join(f'{w:g}' for w in tg[late])} rad/s takes up to "
                f"{need.max():.0f} s, but the steady window starts at {duration - window:g} s: "
                f"use --duration >= {np.ceil(need.max() + window):.0f}"
            )
    return out


#: the configurations the harness evaluates controllers in (a lower disc and a motor)
EVALUATED_CONFIGS = ("torsional", "coupled", "lateral")

#: highest target speed of the lower disc (rad/s) the harness accepts
TARGET_MAX = 50.0

#: longest run (s) the harness simulates per controller, configuration, scenario and target
DURATION_MAX = 3600.0


def check_evaluation_options(
    controllers: Sequence[str],
    configs: Sequence[str],
    targets: Sequence[float],
    duration: float,
    window: float,
    plants: int = 20,
    seed: int = 0,
    workers: int = 2,
    names: Mapping[str, str] | None = None,
) -> None:
    """Refuse, before any run, the settings of :func:`evaluate` it cannot use.

    Parameters
    ----------
    controllers : sequence of str
        Controller names, ``NAME@MS`` or ``agent:PATH`` (the path must exist).
    configs : sequence of str
        Configurations, each one of :data:`EVALUATED_CONFIGS`.
    targets : sequence of float
        Target speeds (rad/s): finite, in (0, :data:`TARGET_MAX`].
    duration, window : float
        Run length and steady-state window (s): finite, 0 < window < duration <= :data:`DURATION_MAX`.
    plants, seed, workers : int
        Plants of a population (>= 1), seed (>= 0), processes (>= 1).
    names : mapping of str to str, optional
        How to call each setting in the messages (the command line gives its options).

    Raises
    ------
    InputError
        Naming the setting, the value and what would be valid.
    MissingFileError
        An ``agent:PATH`` whose path does not exist.
    """
    import math
    from pathlib import Path

    from drillgym.errors import MissingFileError

    from .. import available
    from ..registry import split_period

    n = {k: k for k in ("controllers", "configs", "targets", "duration", "window", "plants", "seed", "workers")}
    n.update(names or {})
    if not list(controllers):
        raise InputError(f"{n['controllers']}: no controller given; choose from {', '.join(available())}")
    for c in controllers:
        if c.startswith("agent:"):
            path = Path(c[len("agent:") :])
            if not str(path).strip() or not path.exists():
                raise MissingFileError(f"{n['controllers']} {c}: {path} not found (a policy.npz or a run directory)")
            continue  # loaded by check_agents, once the configurations are known
        try:
            name = split_period(c)[0]
        except InputError as exc:
            raise InputError(f"{n['controllers']} {c}: {exc}") from None
        if name not in available():
            raise InputError(
                f"{n['controllers']}: unknown controller {c!r}; choose from {', '.join(available())} (NAME@MS for "
                "another control period) or agent:PATH"
            )
    _refuse_twice(list(controllers), n["controllers"], "controller")
    if not list(configs):
        raise InputError(f"{n['configs']}: no configuration given; choose from {', '.join(EVALUATED_CONFIGS)}")
    for c in configs:
        try:
            label = parse_configuration(c).label
        except InputError as exc:
            raise InputError(f"{n['configs']}: {' '.join(str(exc).split())}") from None
        if label not in EVALUATED_CONFIGS:
            raise InputError(
                f"{n['configs']} {c}: controllers are evaluated in {', '.join(EVALUATED_CONFIGS)} (a motor and a "
                "lower disc)"
            )
    _refuse_twice([parse_configuration(c).label for c in configs], n["configs"], "configuration")
    tg = list(targets)
    if not tg:
        raise InputError(f"{n['targets']}: no target speed given")
    for v in tg:
        if not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= TARGET_MAX):
            raise InputError(f"{n['targets']}: target speeds must be in (0, {TARGET_MAX:g}] rad/s, got {v!r}")
    for key, v in (("duration", duration), ("window", window)):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"{n[key]} must be a positive finite number of seconds, got {v!r}")
    if duration > DURATION_MAX:
        raise InputError(f"{n['duration']} must be at most {DURATION_MAX:g} s per run, got {duration:g}")
    if not window < duration:
        raise InputError(f"{n['window']} ({window:g} s) must be shorter than {n['duration']} ({duration:g} s)")
    for key, v, lo in (("plants", plants, 1), ("seed", seed, 0), ("workers", workers, 1)):
        if isinstance(v, bool) or int(v) != v or v < lo:
            raise InputError(f"{n[key]} must be an integer >= {lo}, got {v!r}")
    check_agents(controllers, configs, tg[0], n["controllers"])


def check_agents(controllers: Sequence[str], configs: Sequence[str], omega_ref: float, name: str) -> None:
    """Load every ``agent:PATH`` of ``controllers`` once per configuration, before any job: a file that is
    not a policy, or a policy of another configuration, is refused naming ``name`` and the path."""
    from drillgym.errors import DrillgymError

    from ..registry import make

    for c in controllers:
        if not c.startswith("agent:"):
            continue
        for cfg in configs:
            try:
                make(c, config=parse_configuration(cfg).label, omega_ref=omega_ref)
            except DrillgymError as exc:
                msg = " ".join(str(exc).split())
                raise InputError(f"{name} {c}: {msg}") from exc


def _refuse_twice(items: list, option: str, what: str) -> None:
    """Refuse a list that names one item twice (each would be run and reported twice, as if two)."""
    seen = set()
    for item in items:
        if item in seen:
            raise InputError(f"{option}: {what} {item!r} is given twice; give each once")
        seen.add(item)


def evaluate(
    controllers: Sequence[str],
    configs: Sequence[str] = ("torsional", "coupled"),
    scenarios: Sequence[str | Scenario] = ("rest",),
    targets: Sequence[float] = DEFAULT_TARGETS,
    *,
    duration: float = DEFAULT_DURATION,
    window: float = DEFAULT_WINDOW,
    params: RigParams | None = None,
    executor: Executor | None = None,
    workers: int = 2,
    progress: bool = True,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
    plants: int | None = None,
    seed: int = 0,
    uncertainty: Any = None,
    plants_per_job: int = 10,
    model: Any = None,
    identify: Any = None,
    plants_file: Any = None,
    trust: bool = False,
) -> list[dict]:
    """Evaluate every controller in every configuration and scenario on the target grid.

    Each run starts as its scenario says, lasts ``duration`` and is judged on its last ``window``
    seconds (:mod:`controllers.evaluation.metrics`).  Warns (``warnings.warn``) when a controller's
    approach ends inside the steady window.

    Parameters
    ----------
    controllers : sequence of str
        Controller names (:func:`controllers.available`), ``NAME@MS`` for another control period (ms),
        or ``agent:PATH`` for an exported policy.
    configs : sequence of str, optional
        Rig configurations.  Default ``("torsional", "coupled")``.
    scenarios : sequence of str or Scenario, optional
        Scenarios by name (:data:`controllers.evaluation.scenarios.SCENARIOS`: ``rest``, ``cycle``,
        ``friction-20``, ``friction+20``, ``noisy``, ``plants``) or :class:`Scenario` objects.
    targets : sequence of float, optional
        Target speeds of the lower disc (rad/s).  Default 0.5 to 8 in steps of 0.5.
    duration : float, optional
        Length of each run (s).  Default 60.
    window : float, optional
        Steady-state window at the end of each run (s), shorter than ``duration``.  Default 20.
    params : RigParams, optional
        Nominal base parameters of the controllers and the plant; default the identified set.
    executor : concurrent.futures.Executor, optional
        Runs the jobs; default a process pool of ``workers``.
    workers : int, optional
        Size of the default process pool; 1 runs the jobs in this process.
    progress : bool, optional
        Show a progress bar.
    effects : optional
        Hidden effects of the plant (names, ``"path/to/file.py:NAME"``, classes or instances), unknown to
        the controllers.  Not with the ``plants`` scenario (the population brings its own).
    effect_params : mapping of str to float, optional
        The hidden effects' parameter values by name.
    plants : int, optional
        Number of plants a population scenario draws.  Default 20 (not with ``plants_file``).
    seed : int, optional
        Seed of the plant population and of the measurement noise.
    uncertainty : str or UncertaintySet, optional
        Uncertainty set of the population (a YAML path or
        :class:`controllers.evaluation.population.UncertaintySet`); default ``plants.yaml`` (not with
        ``plants_file``).
    plants_per_job : int, optional
        Plants per job of a population scenario.
    model : drillgym.Model or path, optional
        The controllers' own model (base parameters and effects, e.g. identified): ``observer``, ``lqg`` and
        ``lqg-2enc`` run its effects, the others its base parameters.  Default: ``params`` without effects.
    identify : ExcitationOptions or bool, optional
        For a population scenario: identify each plant first (:mod:`.identify`: an excitation run, diagnose,
        identify) and build every controller on that plant's identified model; the rows gain the identified
        values (``id_<name>``), the effects selected and the identification time (``identify_s``).  A mapping
        plant index -> :class:`.identify.IdentifiedPlant` (e.g. read back by
        :func:`.identify.load_identified`) is used as given, for every plant of the population.
    plants_file : str, path or PlantSet, optional
        For a population scenario: the plants the user wrote instead of drawn ones (a plants file,
        :mod:`.plants_file`, or what :func:`.plants_file.load_plants` read); the rows name each plant
        (``plant_name``) and its effects (``effects``).  Plants of one composition run as one batch.
    trust : bool, optional
        Import the plants file's effect files even when they lie outside its folder (importing runs them).

    Returns
    -------
    list of dict
        One row per controller, configuration, scenario, plant and target, sorted in that order: the
        metrics of :func:`controllers.evaluation.metrics.run_metrics` and the plant's label (``plant``).

    Raises
    ------
    InputError
        An unknown controller or scenario, a bad window, hidden effects with the plants scenario, a bad
        number of plants, or a plants file that cannot be used (naming the file, the plant and what is wrong).
    """
    n_drawn = 20 if plants is None else plants
    check_evaluation_options(controllers, configs, targets, duration, window, n_drawn, seed, workers)
    scen = [SCENARIOS[s] if isinstance(s, str) and s in SCENARIOS else s for s in scenarios]
    for s in scen:
        if not isinstance(s, Scenario):
            raise InputError(f"unknown scenario {s!r}; choose from {', '.join(SCENARIOS)}")
    for c in configs:
        parse_configuration(c)
    if not (0 < window < duration):
        raise InputError(f"window ({window} s) must be positive and shorter than duration ({duration} s)")
    from .. import available
    from ..registry import split_period

    for c in controllers:
        if not c.startswith("agent:") and split_period(c)[0] not in available():
            raise InputError(
                f"unknown controller {c!r}; choose from {', '.join(available())} (NAME@MS for another "
                "control period) or agent:PATH"
            )
    comp, values = compose(effects, effect_params)  # errors name the effect before any job starts
    if model is not None:
        from ..model import model_of

        model = model_of(model)
        for c in controllers:  # refusals (an effect a controller cannot use) before any job starts
            for cfg in configs if not c.startswith("agent:") else ():
                build_controller(c, cfg, np.asarray(targets, dtype=float)[:1], RigParams(), model)
    pop_kw: dict = {}
    chunks: list[list[int]] = [[]]
    if any(s.population for s in scen):
        if comp.effects:
            raise InputError("the plants scenario draws its own effects; do not combine it with --add-effect")
        pop_kw, chunks = _population(plants, seed, uncertainty, plants_file, trust, params, configs, plants_per_job)
        if identify:
            if model is not None:
                raise InputError(
                    "identify builds the controllers on each plant's identified model; do not give a model"
                )
            if isinstance(identify, Mapping):
                pop_kw["identified"] = _given_identification(identify, pop_kw["n_plants"])
    elif identify:
        raise InputError("identify applies to a population of plants: add the scenario 'plants'")
    elif plants_file is not None:
        raise InputError("plants_file applies to a population of plants: add the scenario 'plants'")
    for cfg in configs:
        for line in short_run_warnings(controllers, cfg, targets, duration, window, params):
            warnings.warn(line, stacklevel=2)
    pdict = params.to_dict() if params is not None else None
    u_folds = {}
    if any(s.start == "cycle" for s in scen):
        from ..baseline import stick_slip_region

        u_folds = {c: stick_slip_region(c, params or RigParams()).u_fold for c in configs}
    jobs = [
        (c, cfg, s, ch)
        for c in controllers
        for cfg in configs
        for s in scen
        for ch in (chunks if s.population else [[]])
    ]
    kw = dict(
        targets=list(map(float, targets)),
        duration=duration,
        window=window,
        params=pdict,
        effects=comp.specs(),
        effect_params=values,
        seed=seed,
        model=model,
    )  # specs: a user file's effect reaches workers

    def job_kw(s: Scenario, ch: list[int]) -> dict:
        if not s.population:
            return {}
        ident = pop_kw.get("identified")
        return {**pop_kw, "identified": {k: ident[k] for k in ch} if ident else None}

    per_plant = bool(identify) and not isinstance(identify, Mapping)  # identified in each plant's own task
    calls = [
        (run_job, (c, cfg, s), {"u_fold": u_folds.get(cfg), "plants": ch, **job_kw(s, ch), **kw})
        for c, cfg, s, ch in jobs
        if not (per_plant and s.population)
    ]
    if per_plant:
        calls = _plant_tasks(controllers, configs, scen, pop_kw, kw, params, identify) + calls  # the longest first
    unit = "plant" if per_plant else "job"
    desc = "identify and evaluate" if per_plant else "evaluate"
    rows = [row for part in run_all(calls, executor, workers, desc, unit, progress) for row in part]
    order = {c: i for i, c in enumerate(controllers)}
    rows.sort(
        key=lambda r: (
            order[r["controller"]],
            r["config"],
            r["scenario"],
            r["plant"] if isinstance(r.get("plant"), int) else -1,
            r["omega_ref"],
        )
    )
    return rows


def _plant_tasks(
    controllers: Sequence[str],
    configs: Sequence[str],
    scenarios: Sequence[Scenario],
    pop_kw: dict,
    kw: dict,
    params: RigParams | None,
    identify: Any,
) -> list[tuple]:
    """One task per plant of the population (:func:`.population_jobs.identify_then_run`): identify it in the
    first configuration, then run every controller, configuration and population scenario on it."""
    n, plant_set = pop_kw["n_plants"], pop_kw.get("plant_set")
    jobs = [(c, cfg, s) for c in controllers for cfg in configs for s in scenarios if s.population]
    return [
        (
            identify_then_run,
            (
                identify_arguments(k, n, kw["seed"], pop_kw["uncertainty"], params, identify, configs[0], plant_set),
                [(run_job, job, {"plants": [k], **pop_kw, **kw}) for job in jobs],
            ),
            {},
        )
        for k in range(n)
    ]


def _given_identification(identified: Mapping[int, Any], n_plants: int) -> dict[int, Any]:
    """The identification given for every plant ``0..n_plants-1`` (``evaluate(identify=mapping)``)."""
    missing = [k for k in range(n_plants) if k not in identified]
    if missing:
        raise InputError(f"identify: no identified model given for plant {missing[0]} (of {n_plants})")
    return {k: identified[k] for k in range(n_plants)}


def _population(
    plants: int | None,
    seed: int,
    uncertainty: Any,
    plants_file: Any,
    trust: bool,
    params: RigParams | None,
    configs: Sequence[str],
    per_job: int,
) -> tuple[dict, list[list[int]]]:
    """The population's job arguments (``n_plants``, ``uncertainty``, ``plant_set``) and its chunks of plant
    indices (at most ``per_job`` plants each; a user's plants gathered by composition), every refusal before
    any job starts."""
    if plants_file is not None:
        if plants is not None or uncertainty is not None:
            raise InputError("plants_file holds the plants: give neither plants nor uncertainty beside it")
        ps = plants_file if isinstance(plants_file, PlantSet) else load_plants(plants_file, trust=trust, params=params)
        for c in configs:
            ps.refuse_not_acting(parse_configuration(c).label)
        chunks = [g[a : a + per_job] for g in ps.groups() for a in range(0, len(g), per_job)]
        return {"n_plants": ps.n, "uncertainty": None, "plant_set": ps}, chunks
    n = 20 if plants is None else plants
    if int(n) != n or n < 1:
        raise InputError(f"the number of plants must be a positive integer, got {n!r}")
    us = uncertainty if isinstance(uncertainty, UncertaintySet) else load_uncertainty(uncertainty)
    sample_plants(1, seed, us, params)  # errors of the set before any job starts
    chunks = [list(range(a, min(a + per_job, int(n)))) for a in range(0, int(n), per_job)]
    return {"n_plants": int(n), "uncertainty": us}, chunks
