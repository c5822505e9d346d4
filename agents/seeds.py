"""Several seeds of one training: run them (in parallel where cores allow), then one table and one figure.

``train_seeds(env_id, algo, out, seeds=[1, 2, 3], ...)`` trains seed s into ``out/seed_<s>/`` (each an
ordinary :func:`agents.train.train` run with its evaluation callback), ``workers`` processes at a time
(default: min(#seeds, CPU cores); each process uses one torch thread).  Then per seed:

* ``final_reward``: mean return of the deterministic policy over the evaluation episodes at the end;
* ``best_reward``: the best of the evaluation curve (its model is ``seed_<s>/best/``);
* ``lowest_held``: the lowest held target from rest (rad/s, :mod:`agents.evaluation`) of the final policy;
  a policy that holds no target counts as :data:`NOT_HELD` (above the grid) in the aggregates;
* ``wall_time``: the seed's training time (s).

Aggregates as rliable recommends for few runs: the interquartile mean (IQM, the mean of the middle 50 %,
``scipy.stats.trim_mean(x, 0.25)``) with a percentile-bootstrap 95 % confidence interval
(``scipy.stats.bootstrap``, 2000 resamples; NaN for a single seed, the value itself when all seeds agree), and
the median.  Files:
``results.csv`` (one row per seed), ``results.md`` (that table and the aggregates), ``learning_curves.png``
(evaluation return against environment steps, one line per seed, IQM over the seeds in bold).
"""

from __future__ import annotations

import csv
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import InputError
from drillgym.io import create_directory

__all__ = ["train_seeds", "iqm", "iqm_ci", "SeedSummary", "NOT_HELD", "write_results", "plot_learning_curves"]

#: lowest held target (rad/s) counted for a policy that holds no target of the grid (above its 8 rad/s)
NOT_HELD = 8.5
METRICS = ("lowest_held", "final_reward", "best_reward", "wall_time")


def iqm(x: Sequence[float]) -> float:
    """Interquartile mean: the mean of the middle 50 % of the values (scipy's 25 % trimmed mean)."""
    from scipy.stats import trim_mean

    return float(trim_mean(np.asarray(x, dtype=float), 0.25))


def iqm_ci(x: Sequence[float], confidence: float = 0.95, n_resamples: int = 2000, seed: int = 0) -> tuple[float, float]:
    """Percentile-bootstrap confidence interval of the interquartile mean.

    Parameters
    ----------
    x : sequence of float
        The values (one per seed).
    confidence : float, optional
        Confidence level.  Default 0.95.
    n_resamples : int, optional
        Bootstrap resamples.  Default 2000.
    seed : int, optional
        Seed of the resampling.

    Returns
    -------
    low, high : float
        The interval; (NaN, NaN) for fewer than 2 values, (x, x) when all values are equal.
    """
    from scipy.stats import bootstrap

    a = np.asarray(x, dtype=float)
    if a.size < 2:
        return float("nan"), float("nan")
    if np.ptp(a) == 0:  # every seed alike: the bootstrap has nothing to resample
        return float(a[0]), float(a[0])
    res = bootstrap(
        (a,),
        lambda v, axis: np.apply_along_axis(iqm, axis, v),
        confidence_level=confidence,
        n_resamples=n_resamples,
        method="percentile",
        random_state=seed,
        vectorized=True,
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


@dataclass
class SeedSummary:
    """Per-seed results (rows) and their aggregates per metric: {metric: {iqm, ci_low, ci_high, median}}."""

    rows: list[dict[str, Any]]
    aggregates: dict[str, dict[str, float]]
    out: Path


def _train_one(kwargs: dict[str, Any]) -> dict[str, Any]:
    """Worker: one seed's training and evaluation (runs in its own process)."""
    from .evaluation import lowest_held_target
    from .train import train

    evaluate = kwargs.pop("evaluate_held")
    t0 = time.perf_counter()
    res = train(**kwargs)
    wall = time.perf_counter() - t0
    row = {
        "seed": kwargs["seed"],
        "timesteps": res.timesteps,
        "wall_time": round(wall, 1),
        "train_time": round(res.wall_time, 1),
    }
    ev = Path(res.out) / "evaluations.npz"
    if ev.is_file():
        with np.load(ev) as z:
            means = z["results"].mean(axis=1)
        row.update(final_reward=float(means[-1]), best_reward=float(means.max()))
    if evaluate and res.policy_path is not None:  # on the run's model's plant, if it has one
        row["lowest_held"] = lowest_held_target(
            res.policy_path, model=kwargs.get("model"), trust=bool(kwargs.get("trust", False))
        )
    return row


def train_seeds(
    env_id: str,
    algo: str,
    out: str | Path,
    seeds: Sequence[int],
    *,
    workers: int | None = None,
    evaluate_held: bool = True,
    ray: str | None = None,
    **train_kwargs: Any,
) -> SeedSummary:
    """Train ``algo`` on ``env_id`` once per seed into ``out/seed_<s>/`` and write the results.

    Parameters
    ----------
    env_id : str
        Gymnasium id of the environment.
    algo : str
        Algorithm (:data:`agents.train.ALGOS`).
    out : str or path
        Directory of the runs and of the results (``results.csv``, ``results.md``,
        ``learning_curves.png``; module docstring).
    seeds : sequence of int
        The seeds, at least one.
    workers : int, optional
        Seeds trained at once (processes); default one per seed up to the CPU count.
    evaluate_held : bool, optional
        Also measure each seed's lowest held target from rest (rad/s).
    ray : str, optional
        Run the seeds as Ray Tune trials there: ``"local"``, ``"auto"`` or an address
        (:func:`drillgym.tune.run_trials`).
    **train_kwargs
        Keywords of :func:`agents.train.train`; ``eval_every`` defaults to a twentieth of the run, at least
        10,000 steps, so that every seed has a learning curve.

    Returns
    -------
    SeedSummary
        Per-seed rows and their aggregates per metric (IQM, bootstrap interval, median).
    """
    out = create_directory(out)
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise InputError("need at least one seed")
    workers = min(len(seeds), os.cpu_count() or 1) if workers is None else int(workers)
    if train_kwargs.get("eval_every") is None:
        from .train import planned_timesteps

        n = planned_timesteps(
            env_id, algo, train_kwargs.get("timesteps"), train_kwargs.get("hyperparams"), train_kwargs.get("overrides")
        )
        train_kwargs["eval_every"] = max(10_000, n // 20)
    jobs = [
        dict(
            train_kwargs,
            env_id=env_id,
            algo=algo,
            out=out / f"seed_{s}",
            seed=s,
            evaluate_held=evaluate_held,
            progress=False,
        )
        for s in seeds
    ]
    if ray is not None:
        from drillgym.tune import run_trials

        rows = run_trials(
            _train_one,
            jobs,
            ray=ray,
            workers=workers if ray == "local" else None,
            name=f"{algo}_seeds",
            storage=out.resolve() / "tune",
        )
    elif workers <= 1:
        rows = [_train_one(j) for j in jobs]
    else:
        with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as ex:
            rows = list(ex.map(_train_one, jobs))
    summary = write_results(rows, out)
    plot_learning_curves([out / f"seed_{s}" for s in seeds], out / "learning_curves.png")
    return summary


def write_results(rows: list[dict[str, Any]], out: Path) -> SeedSummary:
    """``results.csv`` and ``results.md`` of per-seed ``rows`` in ``out``; returns the summary."""
    out = Path(out)
    aggregates: dict[str, dict[str, float]] = {}
    for m in METRICS:
        vals = [r[m] for r in rows if m in r]
        if not vals:
            continue
        v = np.array([NOT_HELD if (m == "lowest_held" and not np.isfinite(x)) else x for x in vals], dtype=float)
        lo, hi = iqm_ci(v)
        aggregates[m] = {"iqm": iqm(v), "ci_low": lo, "ci_high": hi, "median": float(np.median(v))}
    keys = ["seed", "timesteps", "wall_time", "train_time", *[m for m in METRICS if m not in ("wall_time",)]]
    keys = [k for k in dict.fromkeys(keys) if any(k in r for r in rows)]
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    fmt = lambda v: f"{v:.3g}" if isinstance(v, float) else str(v)  # noqa: E731
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    lines += [
        "",
        f"Over {len(rows)} seeds (lowest held target: none held counts as {NOT_HELD} rad/s):",
        "",
        "| metric | IQM | 95 % CI (bootstrap) | median |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {m} | {a['iqm']:.3g} | [{a['ci_low']:.3g}, {a['ci_high']:.3g}] | {a['median']:.3g} |"
        for m, a in aggregates.items()
    ]
    (out / "results.md").write_text("\n".join(lines) + "\n")
    return SeedSummary(rows, aggregates, out)


def plot_learning_curves(runs: Sequence[Path], path: Path) -> Path | None:
    """Evaluation return against environment steps of each run's ``evaluations.npz`` (one line per run,
    the IQM over the runs in bold where their steps agree); None when no run has one."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = []
    for r in runs:
        f = Path(r) / "evaluations.npz"
        if f.is_file():
            with np.load(f) as z:
                curves.append((Path(r).name, z["timesteps"], z["results"].mean(axis=1)))
    if not curves:
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, t, y in curves:
        ax.plot(t, y, lw=1, alpha=0.6, label=name)
    n = min(len(t) for _, t, _ in curves)
    if len(curves) > 1 and n > 0:
        Y = np.array([y[:n] for _, _, y in curves])
        ax.plot(curves[0][1][:n], [iqm(c) for c in Y.T], "k", lw=2.5, label="IQM")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("evaluation return (deterministic policy)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
