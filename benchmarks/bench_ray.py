"""Overhead of Ray against the local process pool: a plant population on the evaluation harness.

The same work on both backends, each with ``--workers`` workers on this machine: ``--plants`` plants drawn
with ``--seed`` (``controllers/evaluation/plants.yaml``), every controller, the targets, shipped as jobs of
``--plants-per-job`` plants (one batched core call each).  Rounds alternate the backends (the machine is
shared, its load drifts); the first round of each backend is cold (worker processes start and import
drillgym, kernels load from the disk cache), later rounds reuse the workers.  The rows of both backends
must be identical.  Then: Ray's cost per task (empty tasks), one job's time, and how the work would
split over N machines.

Run: .venv/bin/python benchmarks/bench_ray.py [--plants 20] [--workers 2] [--rounds 3]
(on a checkout nobody edits meanwhile: a source edit changes the kernels that a worker started later compiles)
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
import warnings

from controllers.evaluation import evaluate
from drillgym.parallel import LocalExecutor, RayExecutor, connect_ray, map_ordered


def _noop(i: int) -> int:
    return i


def _rows_key(rows: list[dict]) -> list[tuple]:
    return [tuple(sorted((k, repr(v)) for k, v in r.items())) for r in rows]


def _differences(a: list[tuple], b: list[tuple]) -> str:
    """How many values differ between two row sets (and the first one), '' when identical."""
    diff = [(x, y) for ra, rb in zip(a, b) for x, y in zip(ra, rb) if x != y]
    if not diff and len(a) == len(b):
        return ""
    return f"{len(diff)} values differ, e.g. {diff[0][0]} vs {diff[0][1]}" if diff else "row counts differ"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--plants", type=int, default=20)
    ap.add_argument("--plants-per-job", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--controllers", default="baseline,observer")
    ap.add_argument("--targets", default="2,4,6")
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--window", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    warnings.simplefilter("ignore", UserWarning)  # short runs judge the approach: irrelevant to the overhead
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # exit through Ray's shutdown, leaving no processes
    ctrls = a.controllers.split(",")
    targets = [float(v) for v in a.targets.split(",")]
    kw = dict(
        targets=targets,
        duration=a.duration,
        window=a.window,
        plants=a.plants,
        seed=a.seed,
        plants_per_job=a.plants_per_job,
        progress=False,
    )
    n_jobs = len(ctrls) * math.ceil(a.plants / a.plants_per_job)
    n_runs = len(ctrls) * a.plants * len(targets)
    print(
        f"population of {a.plants} plants x {len(targets)} targets x {len(ctrls)} controllers = {n_runs} closed-loop "
        f"runs of {a.duration:g} s, in {n_jobs} jobs of {a.plants_per_job} plants; {a.workers} workers"
    )

    t = time.perf_counter()  # compile (or load) the kernels here once, so both backends find them on disk
    evaluate(
        ctrls,
        ["torsional"],
        ["plants"],
        **{**kw, "plants": 1, "plants_per_job": 1, "duration": 2.0, "window": 1.0},
        workers=1,
    )
    print(f"kernel warm-up in this process: {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    connect_ray("local", num_cpus=a.workers)
    t_init = time.perf_counter() - t
    print(
        f"Ray start-up (ray.init, local instance of {a.workers} CPUs): {t_init:.1f} s (once per session; "
        "none with --ray auto on a running cluster)"
    )

    walls: dict[str, list[float]] = {"local pool": [], "ray": []}
    results = {}
    with LocalExecutor(a.workers) as pool, RayExecutor(None) as ray_ex:
        for r in range(a.rounds):
            order = [("local pool", pool), ("ray", ray_ex)]
            for name, ex in order if r % 2 == 0 else order[::-1]:
                t = time.perf_counter()
                rows = evaluate(ctrls, ["torsional"], ["plants"], executor=ex, **kw)
                walls[name].append(time.perf_counter() - t)
                results.setdefault(name, _rows_key(rows))
                assert _rows_key(rows) == results[name], f"{name}: rows changed between rounds"
            print(
                f"round {r + 1}: local pool {walls['local pool'][-1]:6.1f} s   ray {walls['ray'][-1]:6.1f} s"
                + ("   (cold: workers start)" if r == 0 else "")
            )
        identical = results["local pool"] == results["ray"]
        t = time.perf_counter()
        n_noop = 200
        map_ordered(ray_ex, _noop, [(i,) for i in range(n_noop)])
        per_task = (time.perf_counter() - t) / n_noop * a.workers
    t = time.perf_counter()
    evaluate(ctrls[:1], ["torsional"], ["plants"], workers=1, **{**kw, "plants": a.plants_per_job})
    t_job = time.perf_counter() - t

    def summary(xs: list[float]) -> str:
        warm = xs[1:] or xs
        return f"cold {xs[0]:6.1f} s, warm best {min(warm):6.1f} s, warm median {sorted(warm)[len(warm) // 2]:6.1f} s"

    lp, ry = walls["local pool"], walls["ray"]
    ratios = sorted(y / x for x, y in zip(lp[1:], ry[1:]))
    warm = lambda xs: min(xs[1:] or xs)  # noqa: E731
    print(f"\nlocal pool : {summary(lp)}")
    print(f"ray        : {summary(ry)}")
    print(
        f"Ray overhead against the local pool at {a.workers} workers: cold {100 * (ry[0] / lp[0] - 1):+.1f} %, "
        f"warm {100 * (warm(ry) / warm(lp) - 1):+.1f} % (goal <= 15 %); with ray.init included once: "
        f"{100 * ((sum(ry) + t_init) / sum(lp) - 1):+.1f} % over {a.rounds} rounds"
    )
    if len(ratios):
        print(
            f"paired warm rounds (ray / local pool of the same round): "
            f"{', '.join(f'{100 * (q - 1):+.1f} %' for q in ratios)}; "
            f"median {100 * (ratios[len(ratios) // 2] - 1):+.1f} %"
        )
    diff = _differences(results["local pool"], results["ray"])
    print(f"rows identical on both backends: {identical}" + (f" ({diff})" if diff else ""))
    print(
        f"Ray's own cost per task (empty tasks, {a.workers} workers): {1e3 * per_task:.2f} ms; one job "
        f"({ctrls[0]}, {a.plants_per_job} plants x {len(targets)} targets) in one process: {t_job:.1f} s"
    )

    print(
        "\nhow the work splits over N machines (2 cores each, one Ray worker per core): a task is one job of "
        "plants_per_job plants x every target as one batched core call; tasks = controllers x ceil(plants / "
        "plants_per_job); wall ~ ceil(tasks / workers) x the slowest job"
    )
    per_plant = warm(lp) * a.workers / (a.plants * len(ctrls))  # CPU s per (plant, controller), mean
    print(f"measured: {per_plant:.2f} CPU s per plant and controller (mean over the controllers, warm local pool)")
    print(
        f"{'plants':>7} {'machines':>8} {'workers':>7} {'plants/job':>10} {'tasks':>6} {'waves':>5} "
        f"{'est. wall':>9} {'Ray cost / compute':>18}"
    )
    for plants in (a.plants, 1000):
        for n in (1, 2, 4, 8, 16):
            w = 2 * n
            ppj = max(1, math.ceil(plants * len(ctrls) / (2 * w)))  # two tasks per worker: balance, little overhead
            ppj = min(ppj, plants)
            tasks = len(ctrls) * math.ceil(plants / ppj)
            waves = math.ceil(tasks / w)
            frac = per_task / (t_job * ppj / a.plants_per_job)
            wall = waves * ppj * per_plant + waves * per_task
            print(f"{plants:>7} {n:>8} {w:>7} {ppj:>10} {tasks:>6} {waves:>5} {wall:>8.1f}s {100 * frac:>17.2f}%")


if __name__ == "__main__":
    main()
