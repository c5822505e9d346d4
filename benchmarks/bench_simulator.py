"""Simulator speed: simulated seconds per wall-clock second at dt = 1 ms (RK4, exact stick).

Prints, for torsional and coupled, one trajectory and a batch of 256 (one core,
and all cores), the real-time factor  (trajectories x simulated s) / wall s.
Targets: batch >= 20,000x torsional, >= 2,000x coupled on
one core; one trajectory >= 2,000x torsional.

    .venv/bin/python benchmarks/bench_simulator.py [--duration 60]

Each figure is the best of 5 runs (timeit's convention: on a shared virtual machine the
spread between runs of the same batch reaches +-25 %).  On AVX-512 hosts drillgym lets LLVM
use 512-bit vectors (``drillgym/_simd.py``); ``DRILLGYM_SIMD=256`` measures AVX2 width.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import get_num_threads

from drillgym import simulate_batch

TARGETS = {("torsional", "single"): 2000, ("torsional", "batch"): 20000, ("coupled", "batch"): 2000}


SINGLE_VOLTAGES = (0.5, 1.5, 2.5, 3.5, 4.5)  # V: stick-slip, steady slip and the coexistence region


def realtime_factor(config: str, n: int, duration: float, parallel: bool, repeats: int = 5) -> float:
    """Best of `repeats`: trajectories x duration / wall time.  Inputs span stick-slip and steady
    slip: a batch of n over 0.5-4.5 V, or (n = 1) one run after the other at SINGLE_VOLTAGES."""
    simulate_batch(config, np.array([1.0]), 1.0, record_every=1000, parallel=parallel)  # compile / load cache
    runs = [np.array([v]) for v in SINGLE_VOLTAGES] if n == 1 else [np.linspace(0.5, 4.5, n)]
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for u in runs:
            simulate_batch(config, u, duration, record_every=1000, parallel=parallel)
        best = min(best, time.perf_counter() - t0)
    return sum(len(u) for u in runs) * duration / best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="simulated seconds per trajectory")
    args = ap.parse_args()
    print(f"dt = 1 ms, RK4, exact (event-driven) stick; {os.cpu_count()} cores, numba threads {get_num_threads()}")
    print(f"{'configuration':<12} {'run':<18} {'real-time factor':>17} {'target':>8}")
    for config in ("torsional", "coupled"):
        for label, n, par in (("single", 1, False), ("batch 256, 1 core", 256, False), ("batch 256, all", 256, True)):
            dur = args.duration if n == 1 else args.duration / 6
            f = realtime_factor(config, n, dur, par)
            key = (config, "single" if n == 1 else "batch")
            target = TARGETS.get(key) if not par else None
            tgt = f"{target:>7}x" if target else "       -"
            print(f"{config:<12} {label:<18} {f:>16,.0f}x {tgt}")


if __name__ == "__main__":
    main()
