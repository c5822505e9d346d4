"""The plant population: every controller on ``--plants`` plants drawn from the default
uncertainty set (controllers/evaluation/plants.yaml), from rest, 60 s runs, the default target grid.

    .venv/bin/python benchmarks/bench_plants.py --seed 0 --plants 20 --config torsional \\
        --out out/plants_seed0

Writes the harness's report (results.csv with one row per controller, plant and target, summary.md
with the median / 90th-percentile lowest held target, plants_lowest_held.png) and prints the table and
the wall time.  Tune on seeds other than 0; seed 0 (and another) is the held-out population.
"""

from __future__ import annotations

import argparse
import csv
import time

from controllers.evaluation import evaluate
from controllers.evaluation.population_report import population_table
from controllers.evaluation.report import write_report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plants", type=int, default=20)
    ap.add_argument("--config", default="torsional", help="comma-separated configurations")
    ap.add_argument("--controllers", default="baseline,pi,descent,softtorque,observer,observer-robust,lqg")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", required=True)
    ap.add_argument("--merge", nargs="*", default=None, help="instead of running: combine these results.csv files")
    a = ap.parse_args()
    if a.merge:
        rows = []
        for path in a.merge:
            with open(path) as f:
                rows += list(csv.DictReader(f))
        write_report(rows, a.out)
        print(population_table(rows))
        return
    t0 = time.perf_counter()
    rows = evaluate(
        a.controllers.split(","), a.config.split(","), ["plants"], plants=a.plants, seed=a.seed, workers=a.workers
    )
    dt = time.perf_counter() - t0
    write_report(rows, a.out)
    print(population_table(rows))
    print(f"{len(rows)} runs in {dt:.1f} s (seed {a.seed}, {a.plants} plants, {a.workers} workers)")


if __name__ == "__main__":
    main()
