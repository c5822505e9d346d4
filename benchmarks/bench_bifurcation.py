"""Benchmark: the full torsional bifurcation diagram (equilibria + Hopf points, periodic branches by
shooting/continuation, sweeps from rest and up/down at 0.05 V steps over 0-5 V) on all cores.

    .venv/bin/python benchmarks/bench_bifurcation.py
"""

import os
import time

from drillgym.bifurcation import compute_diagram


def main() -> None:
    t0 = time.perf_counter()
    d = compute_diagram("torsional", umin=0.0, umax=5.0, sweep_step=0.05, sweep_duration=60.0, sweep_dt=2e-3,
                        staircase=True, ds_max=0.3)
    dt = time.perf_counter() - t0
    n_cyc = sum(len(b.solutions) for b in d.periodic)
    print(f"cores: {os.cpu_count()}")
    print(f"Hopf points (V): {[round(h.u, 4) for h in d.hopf]}")
    print(f"folds (V): {[round(f.u, 4) for f in d.folds]}")
    print(f"periodic solutions: {n_cyc} on {len(d.periodic)} branches; sweep voltages: {len(d.sweeps[0].u)} x "
          f"{len(d.sweeps)} sweeps")
    print(f"full torsional diagram: {dt:.1f} s wall clock (target < 120 s)")


if __name__ == "__main__":
    main()
