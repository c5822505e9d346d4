"""Batch throughput and memory on one core: the recording-cost, coupled-cost and per-core ratios.

Measured interleaved in one run (best of the repeats), so the ratios hold on a shared machine; the
absolute real-time factor needs a quiet one (the load average is printed).

1. 256-lane torsional batch (0.5-4.5 V) recorded at every step against the same batch recorded every
   1000th step: with the default columns (all 18) and with ``record=("t", "omega_l")``.  Goal >= 0.6.
2. coupled batch against torsional batch, both recorded every 1000th step.  Goal >= 0.4.
3. torsional batch real-time factor per core (trajectories x simulated s / wall s).  Goal >= 30,000x
   on a quiet machine.
4. 4096-lane, 60 s torsional batch recorded every 10 steps (all columns, and t + omega_l): peak
   resident memory of a fresh process running it.  Goal <= 4 GB.

    .venv/bin/python benchmarks/bench_batch_throughput.py [--duration 10] [--repeats 5] [--skip-memory]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

from drillgym import simulate_batch

N_LANES = 256


def _timed(config: str, duration: float, record_every: int, record: tuple | None) -> float:
    u = np.linspace(0.5, 4.5, N_LANES)
    t0 = time.perf_counter()
    simulate_batch(config, u, duration, record_every=record_every, record=record)
    return time.perf_counter() - t0


def _memory_child(n: int, duration: float, record: str) -> None:
    """Run in a fresh process: one 4096-lane batch; prints wall time and peak RSS (GB) as JSON."""
    rec = None if record == "all" else tuple(record.split(","))
    simulate_batch("torsional", np.array([1.0] * 8), 0.1, record_every=10, record=rec)  # load the kernels
    t0 = time.perf_counter()
    tr = simulate_batch("torsional", np.linspace(0.5, 4.5, n), duration, record_every=10, record=rec)
    wall = time.perf_counter() - t0
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"wall": wall, "peak_gb": peak_kb / 1024**2, "out_gb": tr.data.nbytes / 1024**3}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0, help="simulated s of the 256-lane batches")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--skip-memory", action="store_true")
    ap.add_argument("--memory-child", nargs=3, metavar=("N", "DURATION", "RECORD"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        n, dur, rec = args.memory_child
        _memory_child(int(n), float(dur), rec)
        return
    cases = {
        "torsional every step, all columns": ("torsional", 1, None),
        "torsional every step, t+omega_l": ("torsional", 1, ("t", "omega_l")),
        "torsional every 1000th": ("torsional", 1000, None),
        "coupled every 1000th": ("coupled", 1000, None),
    }
    for c in cases.values():
        _timed(c[0], 0.1, c[1], c[2])  # compile / load
    best = {k: np.inf for k in cases}
    for _ in range(args.repeats):
        for k, c in cases.items():
            best[k] = min(best[k], _timed(c[0], args.duration, c[1], c[2]))
    load = os.getloadavg()[0]
    print(
        f"{N_LANES} lanes, {args.duration:g} s, dt 1 ms, one core; best of {args.repeats} interleaved; "
        f"load average {load:.1f} on {os.cpu_count()} cores"
    )
    for k in cases:
        print(f"  {k:<36} {best[k]:8.3f} s  {N_LANES * args.duration / best[k]:>10,.0f}x real time")
    ref = best["torsional every 1000th"]
    print(
        f"every step / every 1000th (all columns):  {ref / best['torsional every step, all columns']:.2f} (goal >= 0.6)"
    )
    print(
        f"every step / every 1000th (t, omega_l):    {ref / best['torsional every step, t+omega_l']:.2f} (goal >= 0.6)"
    )
    print(f"coupled / torsional (every 1000th):        {ref / best['coupled every 1000th']:.2f} (goal >= 0.4)")
    print(
        f"torsional batch, one core:                 {N_LANES * args.duration / ref:,.0f}x real time "
        f"(goal >= 30,000x on a quiet machine; load {load:.1f} here)"
    )
    if args.skip_memory:
        return
    for rec in ("all", "t,omega_l"):
        out = subprocess.run(
            [sys.executable, __file__, "--memory-child", "4096", "60", rec], check=True, capture_output=True, text=True
        ).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(
            f"4096 lanes x 60 s, every 10th step, record {rec:<10}: peak RSS {r['peak_gb']:.2f} GB "
            f"(output {r['out_gb']:.2f} GB), {r['wall']:.1f} s (goal <= 4 GB)"
        )


if __name__ == "__main__":
    main()
