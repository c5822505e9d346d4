"""One torsional trajectory (60 s, 1 V, stick-slip from rest): drillgym against an event-driven
scipy ``solve_ivp`` switch model (benchmarks/scipy_switch_model.py, written independently from
docs/model.md, DOP853 and RK45 at rtol 1e-8), timed interleaved in one run on one core.

Prints each method's best wall time over the repeats, the ratio scipy / drillgym, and the largest
lower-disc speed on the limit cycle (last half of the run) of each: the same cycle means the maxima
agree within 1 %.  drillgym records t and omega_l at every 1 ms step (the scipy model only finds the
maxima, by an event); ``rk4`` is the fixed-step default, ``dp45`` the adaptive Dormand-Prince 5(4)
between located events.

    .venv/bin/python benchmarks/bench_single_vs_scipy.py [--repeats 7] [--duration 60]

Figures from a shared machine are ratios of interleaved runs (the load is printed); absolute times
need a quiet machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from scipy_switch_model import simulate_switch_model  # noqa: E402

from drillgym import simulate  # noqa: E402


def _drillgym(method: str, duration: float, u: float) -> float:
    tr = simulate("torsional", u, duration, method=method, record=("t", "omega_l"))
    return float(tr.omega_l[tr.t >= duration / 2].max())


def _scipy(method: str, duration: float, u: float) -> float:
    run = simulate_switch_model(u, duration, method=method, rtol=1e-8, atol=1e-10)
    t, w = np.array(run.t_max), np.array(run.omega_l_max)
    return float(w[t >= duration / 2].max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--u", type=float, default=1.0, help="command (V)")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    runs = {
        "drillgym rk4": lambda: _drillgym("rk4", args.duration, args.u),
        "drillgym dp45": lambda: _drillgym("dp45", args.duration, args.u),
        "scipy DOP853": lambda: _scipy("DOP853", args.duration, args.u),
        "scipy RK45": lambda: _scipy("RK45", args.duration, args.u),
    }
    for f in runs.values():  # compile / load the kernels
        f()
    best = {k: np.inf for k in runs}
    peak = {}
    for _ in range(args.repeats):  # interleaved
        for k, f in runs.items():
            t0 = time.perf_counter()
            peak[k] = f()
            best[k] = min(best[k], time.perf_counter() - t0)
    print(
        f"torsional, {args.duration:g} s at {args.u:g} V from rest; best of {args.repeats} interleaved; "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    print(f"{'method':<16} {'wall s':>9} {'max omega_l (rad/s)':>20}")
    for k in runs:
        print(f"{k:<16} {best[k]:>9.4f} {peak[k]:>20.7f}")
    ref = min(best["scipy DOP853"], best["scipy RK45"])
    for k in ("drillgym rk4", "drillgym dp45"):
        dev = max(abs(peak[k] / peak[s] - 1.0) for s in ("scipy DOP853", "scipy RK45"))
        print(
            f"{k}: faster scipy / drillgym = {ref / best[k]:.1f}x (goal >= 10x); max omega_l differs by "
            f"{100 * dev:.2g} % (goal <= 1 %)"
        )


if __name__ == "__main__":
    main()
