"""Closed-loop throughput: the compiled loop against the step-by-step one, measured in the same run.

``run_closed_loop`` with a controller that offers a compiled law (``compiled=None``) runs plant and law
together in :func:`drillgym.closed_loop.run_compiled_loop`; ``compiled=False`` is today's path (one
compiled ``advance`` and one Python ``act`` per control period).  For ``observer`` at 2 ms and ``pi`` at
its 10 ms, on 1, 64 and 256 lanes (targets 1-6 rad/s, torsional, 8000 counts/rev), and ``lqg`` (10 ms),
``lqg-2enc`` (2 ms) on 256 lanes, the real-time factor per core (lanes x simulated s / wall s, one thread) of
both paths and their ratio, best of the repeats (the two paths taking turns, so that a slow spell of a shared
machine falls on both); each path warmed up first (numba compilation not timed).
A run includes the controller's reset (for the model-based controllers its margin check, one batched eigenvalue
call over the distinct targets: about 3 ms for 256): the "loop" columns leave it out (the wall time of the reset
is measured and subtracted).
Goals (observer, 256 lanes): >= 2,000x real time per core and >= 30x the step-by-step path.  The load
average is printed: the absolute factors need a quiet machine, the ratios hold on a shared one.

The rows ``observer+fx``, ``lqg+fx`` and ``2enc+fx`` (``lqg-2enc``; 256 lanes) run the controllers built on a
model with effects, the plants with the same effects: a motor lag (30 ms), an input delay (5 ms) and a dead zone
(0.3 V, the user file ``examples/effects/motor_dead_zone.py``); ``--model`` runs only those rows.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_closed_loop.py [--duration 2] [--repeats 5] [--model]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import controllers
from controllers.evaluation.runner import run_closed_loop

CASES = [("observer", n) for n in (1, 64, 256)] + [("pi", n) for n in (1, 64, 256)] + [("lqg", 256), ("lqg-2enc", 256)]
MODEL_CASES = [("observer+fx", 256), ("lqg+fx", 256), ("2enc+fx", 256)]
_NAMES = {"2enc+fx": "lqg-2enc+fx"}
EFFECTS = ("motor_lag", "input_delay", "examples/effects/motor_dead_zone.py:dead_zone")
VALUES = {"tau_m": 0.03, "delay": 0.005, "u0": 0.3}


def _rtf(name: str, n: int, duration: float, compiled: bool) -> tuple[float, float]:
    """(whole run, loop without the controller's reset): real-time factors of one run; a name ending in ``+fx``:
    the controller on the model with effects (module doc), the plants with them."""
    from drillgym import Model, RigParams

    ref = np.linspace(1.0, 6.0, n)
    fx = name.endswith("+fx")
    kw = {"model": Model(RigParams(), EFFECTS, VALUES)} if fx else {}
    plant = {"effects": list(EFFECTS), "effect_params": VALUES} if fx else {}
    c = controllers.make(_NAMES.get(name, name).removesuffix("+fx"), config="torsional", omega_ref=ref, **kw)
    spent = []
    reset = c.reset
    c.reset = lambda m: (spent.append(time.perf_counter()), reset(m), spent.append(time.perf_counter()))[1]
    t0 = time.perf_counter()
    run_closed_loop(c, "torsional", ref, duration, compiled=compiled, **plant)
    wall = time.perf_counter() - t0
    return n * duration / wall, n * duration / (wall - (spent[1] - spent[0]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=2.0, help="simulated s of the compiled runs")
    ap.add_argument("--reference-duration", type=float, default=0.5, help="simulated s of the step-by-step runs")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--model", action="store_true", help="only the controllers on a model with effects")
    args = ap.parse_args()
    cases = MODEL_CASES if args.model else CASES + MODEL_CASES
    for name in dict(cases):  # warm up: compile both paths
        for compiled in (True, False):
            _rtf(name, 8, 0.1, compiled)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; real-time factor per core (one thread)")
    print(f"{'':<18}{'whole run (reset included)':^34}{'loop (reset left out)':^34}")
    head = f"{'compiled':>12}{'step-by-step':>14}{'ratio':>8}"
    print(f"{'controller':<12}{'lanes':>6}{head}{head}")
    for name, n in cases:
        fast = fast_loop = slow = slow_loop = 0.0
        for _ in range(args.repeats):  # the paths take turns; each one's best
            a, b = _rtf(name, n, args.duration, True)
            c, d = _rtf(name, n, args.reference_duration, False)
            fast, fast_loop, slow, slow_loop = max(fast, a), max(fast_loop, b), max(slow, c), max(slow_loop, d)
        cols = "".join(f"{a:>11,.0f}x{b:>13,.0f}x{a / b:>7.1f}x" for a, b in ((fast, slow), (fast_loop, slow_loop)))
        print(f"{name:<12}{n:>6}{cols}")


if __name__ == "__main__":
    main()
