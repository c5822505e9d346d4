"""What every job of the harness does: build the controller, read its margins, run the jobs.

Shared by :mod:`.harness` (one controller in one configuration and scenario) and :mod:`.population_jobs`
(a population of plants).
"""

from __future__ import annotations

from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from drillgym import RigParams

__all__ = ["build_controller", "margin_columns", "run_all"]


def margin_columns(ctrl: Any, omega: float) -> dict[str, float | None]:
    """``model_tolerates`` (the relative km error the motor-angle limit tolerates at ``omega``, inf: any) and
    ``model_accuracy`` (what the model file offers; None: unknown) of a controller that reports its margins
    (:mod:`controllers.margin`); no columns for the others."""
    for g in getattr(ctrl, "margins", None) or []:
        if g.omega == omega:
            return {"model_tolerates": g.needed, "model_accuracy": g.achieved}
    return {}


def build_controller(
    controller: str, config: str, omega_ref: np.ndarray, base: RigParams, model: Any = None, **kw
) -> tuple[Any, str]:
    """The controller and the label of the model it runs (``base``, or the effects it uses joined by ``+``).

    With a ``model`` (a :class:`drillgym.Model`), a controller that runs effects is built on
    it, any other on its base parameters (label ``base``); without one, on ``base``.  A learned policy
    (``agent:PATH``) gets the whole model and uses what its structure can: a policy on the observer base runs the
    observer built on it, effects included (label the model's); a plain network warns that it reads none of them
    (label ``base``).
    """
    from .. import make
    from ..registry import CONTROLLERS, split_period

    if model is None:
        return make(controller, config=config, omega_ref=omega_ref, params=base, **kw), "base"
    cls = CONTROLLERS.get(split_period(controller)[0])
    if controller.startswith("agent:"):  # a plain network reads none of the model's effects (it warns): "base"
        ctrl = make(controller, config=config, omega_ref=omega_ref, model=model, **kw)
        return ctrl, model.label if getattr(ctrl, "runs_effects", False) else "base"
    if cls is not None and cls.uses_effects:
        return make(controller, config=config, omega_ref=omega_ref, model=model, **kw), model.label
    return make(controller, config=config, omega_ref=omega_ref, params=model.params, **kw), "base"


def run_all(calls: list, executor: Executor | None, workers: int, desc: str, unit: str, progress: bool) -> list:
    """Run each ``(function, args, kwargs)`` of ``calls`` in turn (no executor, ``workers`` <= 1), else in
    ``executor`` or a pool of ``workers`` processes, under a tqdm bar that is cleared before an error propagates
    (the error is then the one line on stderr); the results in the calls' order."""
    bar = tqdm(total=len(calls), desc=desc, unit=unit, disable=not progress)
    out: list = [None] * len(calls)
    try:
        if executor is None and workers <= 1:
            for i, (fn, a, kw) in enumerate(calls):
                out[i] = fn(*a, **kw)
                bar.update()
        else:
            ex = executor or ProcessPoolExecutor(max_workers=workers)
            try:
                futs = {ex.submit(fn, *a, **kw): i for i, (fn, a, kw) in enumerate(calls)}
                for f in as_completed(futs):
                    out[futs[f]] = f.result()
                    bar.update()
            finally:
                if executor is None:
                    ex.shutdown()
    except BaseException:
        bar.leave = False
        bar.close()
        raise
    bar.close()
    return out
