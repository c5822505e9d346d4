"""Aggregates over policy seeds as RL papers report them (rliable): IQM and stratified-bootstrap intervals.

>>> from agents.benchmark_stats import iqm_interval
>>> iqm_interval([2.5, 3.0, 2.5, 2.5, 3.5])
Aggregate(iqm=2.666..., ci_low=2.5, ci_high=3.333..., seeds=5)
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Aggregate", "iqm_interval", "BOOTSTRAP_REPS"]

#: bootstrap replications of the interval (rliable's default is 50,000; 2,000 give the 2.5/97.5 % quantiles
#: of a handful of seeds to within one grid step)
BOOTSTRAP_REPS = 2000


@dataclass(frozen=True)
class Aggregate:
    """One metric over policy seeds.

    Parameters
    ----------
    iqm : float
        Interquartile mean (the mean of the middle 50 %, ``rliable.metrics.aggregate_iqm``), in the metric's
        unit; inf when a policy seed holding no target (inf) falls into the middle half.
    ci_low, ci_high : float
        Stratified-bootstrap 95 % interval of the IQM (``rliable.library.get_interval_estimates``,
        percentile method); NaN with a single seed (nothing to resample).
    seeds : int
        Number of policy seeds.
    """

    iqm: float
    ci_low: float
    ci_high: float
    seeds: int

    def to_json(self) -> dict:
        """The aggregate as JSON types (inf and NaN as null; :func:`drillgym.io.jsonfile.jsonable` names them)."""
        return {"iqm": self.iqm, "ci_low": self.ci_low, "ci_high": self.ci_high, "seeds": self.seeds}


def iqm_interval(values: Sequence[float], reps: int = BOOTSTRAP_REPS, seed: int = 0) -> Aggregate:
    """IQM of one metric over policy seeds, with its stratified-bootstrap 95 % interval (rliable).

    Parameters
    ----------
    values : sequence of float
        One value per policy seed (inf allowed: a seed holding no target).
    reps : int, optional
        Bootstrap replications.
    seed : int, optional
        Seed of the bootstrap (the interval is reproducible).

    Returns
    -------
    Aggregate
        IQM and interval; the interval is NaN with one seed and, where resamples put inf in the middle
        half, inf.
    """
    from rliable import library, metrics

    x = np.asarray(values, dtype=float).reshape(-1, 1)  # (runs, tasks = 1)
    point = float(metrics.aggregate_iqm(x))
    if x.shape[0] < 2:
        return Aggregate(point, math.nan, math.nan, int(x.shape[0]))
    finite = np.where(np.isinf(x), np.finfo(float).max / 1e3, x)  # rliable's quantiles of inf are NaN
    with warnings.catch_warnings():  # arch's notice that RandomState will give way to Generator
        warnings.simplefilter("ignore", FutureWarning)
        _, interval = library.get_interval_estimates(
            {"policy": finite},
            lambda s: np.array([metrics.aggregate_iqm(s)]),
            reps=int(reps),
            random_state=np.random.RandomState(seed),
        )
    lo, hi = (float(v) for v in interval["policy"][:, 0])
    big = np.finfo(float).max / 1e4
    return Aggregate(point, math.inf if lo > big else lo, math.inf if hi > big else hi, int(x.shape[0]))
