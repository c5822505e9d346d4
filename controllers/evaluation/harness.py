"""The evaluation harness: controllers x configurations x scenarios x target speeds, in parallel.

One job = one controller, one configuration, one scenario, all target speeds
as one batch of the core's simulator (:func:`.runner.run_closed_loop`).  The plant may run
hidden effects (``effects``/``effect_params``, :mod:`drillgym.effects`): the controllers are
always built from the nominal base parameters and never know them.  Jobs
run in a ``concurrent.futures`` executor (processes by default), with a tqdm
progress bar.  Results are rows (dicts) with the metrics of :mod:`.metrics`.

    >>> from controllers.evaluation import evaluate
    >>> rows = evaluate(["baseline", "observer"], ["torsional"], ["rest"], targets=[2.0, 3.0])
    >>> rows = evaluate(["observer"], ["torsional"], ["rest"], targets=[2.0], effects=["input_delay"],
    ...                 effect_params={"delay": 0.03})          # a plant with a hidden delay
"""

from __future__ import annotations

from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from typing import Any, Mapping, Sequence

import numpy as np
from tqdm.auto import tqdm

from drillgym import RigParams, parse_configuration
from drillgym.effects import compose

from .metrics import run_metrics
from .runner import run_closed_loop
from .scenarios import DEFAULT_TARGETS, SCENARIOS, Scenario, cycle_states, plant_params

__all__ = ["evaluate", "run_job", "DEFAULT_DURATION", "DEFAULT_WINDOW"]

DEFAULT_DURATION = 60.0  # s per run
DEFAULT_WINDOW = 20.0  # s of steady state at the end


def run_job(controller: str, config: str, scenario: Scenario, targets: Sequence[float], *,
            duration: float = DEFAULT_DURATION, window: float = DEFAULT_WINDOW, params: dict | None = None,
            u_fold: float | None = None, seed: int = 0, effects: Any = None,
            effect_params: Mapping[str, float] | None = None) -> list[dict]:
    """Run one controller in one configuration and scenario for every target; one row per target.

    ``params``: nominal base parameters (dict; the controller's model and the plant's base);
    ``effects``/``effect_params``: hidden effects of the plant only (specs, classes or a Composition)."""
    from .. import make

    base = RigParams.from_dict(params) if params else RigParams()
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
        raise ValueError(f"scenario start must be 'rest' or 'cycle', got {scenario.start!r}")
    from ..registry import split_period

    kw = {}
    if split_period(controller)[0] in ("observer", "lqg"):
        kw = {"counts_per_rev": scenario.counts_per_rev, "angle_noise": scenario.angle_noise}
    ctrl = make(controller, config=config, omega_ref=tg, params=base, **kw)  # nominal: no hidden effect
    run = run_closed_loop(ctrl, config, tg, duration, params=plant, x0=x0, counts_per_rev=scenario.counts_per_rev,
                          angle_noise=scenario.angle_noise, seed=seed, effects=comp, effect_params=values)
    met = run_metrics(run, window, base)
    rows = []
    for i, w in enumerate(tg):
        row = {"controller": controller, "config": parse_configuration(config).label, "scenario": scenario.name,
               "plant": comp.label, "omega_ref": float(w), "control_dt": float(ctrl.dt)}
        row.update({k: (bool(v[i]) if v.dtype == bool else float(v[i])) for k, v in met.items()})
        rows.append(row)
    return rows


def evaluate(controllers: Sequence[str], configs: Sequence[str] = ("torsional", "coupled"),
             scenarios: Sequence["str | Scenario"] = ("rest",), targets: Sequence[float] = DEFAULT_TARGETS, *,
             duration: float = DEFAULT_DURATION, window: float = DEFAULT_WINDOW, params: RigParams | None = None,
             executor: Executor | None = None, workers: int = 2, progress: bool = True, effects: Any = None,
             effect_params: Mapping[str, float] | None = None) -> list[dict]:
    """Evaluate every controller in every configuration and scenario on the target grid (rad/s).

    ``params``: the nominal base parameters (controllers and plant); ``effects``/``effect_params``:
    hidden effects of the plant (names, 'path/to/file.py:NAME', classes or instances, and their
    values by name), unknown to the controllers.  Rows carry the plant's label (``plant``).
    Runs the jobs in ``executor`` (default: a process pool of ``workers``; ``workers=1``: in this
    process).  Returns the rows of all jobs, sorted by controller, configuration, scenario, target.
    """
    scen = [SCENARIOS[s] if isinstance(s, str) and s in SCENARIOS else s for s in scenarios]
    for s in scen:
        if not isinstance(s, Scenario):
            raise ValueError(f"unknown scenario {s!r}; choose from {', '.join(SCENARIOS)}")
    for c in configs:
        parse_configuration(c)
    if not (0 < window < duration):
        raise ValueError(f"window ({window} s) must be positive and shorter than duration ({duration} s)")
    from .. import available

    from ..registry import split_period

    for c in controllers:
        if not c.startswith("agent:") and split_period(c)[0] not in available():
            raise ValueError(f"unknown controller {c!r}; choose from {', '.join(available())} (NAME@MS for another "
                             "control period) or agent:PATH")
    comp, values = compose(effects, effect_params)  # errors name the effect before any job starts
    pdict = params.to_dict() if params is not None else None
    u_folds = {}
    if any(s.start == "cycle" for s in scen):
        from ..baseline import stick_slip_region
        u_folds = {c: stick_slip_region(c, params or RigParams()).u_fold for c in configs}
    jobs = [(c, cfg, s) for c in controllers for cfg in configs for s in scen]
    kw = dict(targets=list(map(float, targets)), duration=duration, window=window, params=pdict,
              effects=comp.specs(), effect_params=values)  # specs: a user file's effect reaches worker processes
    rows: list[dict] = []
    bar = tqdm(total=len(jobs), desc="evaluate", unit="job", disable=not progress)
    if executor is None and workers <= 1:
        for c, cfg, s in jobs:
            rows += run_job(c, cfg, s, u_fold=u_folds.get(cfg), **kw)
            bar.update()
    else:
        ex = executor or ProcessPoolExecutor(max_workers=workers)
        try:
            futs = [ex.submit(run_job, c, cfg, s, u_fold=u_folds.get(cfg), **kw) for c, cfg, s in jobs]
            for f in as_completed(futs):
                rows += f.result()
                bar.update()
        finally:
            if executor is None:
                ex.shutdown()
    bar.close()
    order = {c: i for i, c in enumerate(controllers)}
    rows.sort(key=lambda r: (order[r["controller"]], r["config"], r["scenario"], r["omega_ref"]))
    return rows
