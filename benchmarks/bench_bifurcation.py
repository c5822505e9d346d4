"""Benchmark: the full torsional bifurcation diagram (equilibria + Hopf points, periodic branches by
shooting/continuation, sweeps from rest and up/down at 0.05 V steps over 0-5 V) on all cores.

    .venv/bin/python benchmarks/bench_bifurcation.py
"""

import argparse
import os
import time

from drillgym.bifurcation import compute_diagram


def main() -> None:
    ap = argparse.ArgumentParser(description="full torsional bifurcation diagram, timed")
    ap.add_argument("--sweep-duration", type=float, default=120.0, help="simulated s per sweep voltage (R7: 120)")
    ap.add_argument("--sweep-dt", type=float, default=1e-3, help="sweep integration step (s) (R7: 1 ms)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    d = compute_diagram(
        "torsional",
        umin=0.0,
        umax=5.0,
        sweep_step=0.05,
        sweep_duration=a.sweep_duration,
        sweep_dt=a.sweep_dt,
        staircase=True,
        ds_max=0.3,
    )
    dt = time.perf_counter() - t0
    n_cyc = sum(len(b.solutions) for b in d.periodic)
    print(f"cores: {os.cpu_count()}")
    print(f"Hopf points (V): {[round(h.u, 4) for h in d.hopf]}")
    print(f"folds (V): {[round(f.u, 4) for f in d.folds]}")
    print(
        f"periodic solutions: {n_cyc} on {len(d.periodic)} branches; sweep voltages: {len(d.sweeps[0].u)} x "
        f"{len(d.sweeps)} sweeps"
    )
    print(f"sweeps: {a.sweep_duration:g} s per voltage at dt = {1e3 * a.sweep_dt:g} ms")
    print(f"full torsional diagram: {dt:.1f} s wall clock (target < 120 s)")


if __name__ == "__main__":
    main()
