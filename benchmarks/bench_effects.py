"""Open effects: the cost of the effect mechanism, measured against its peers in the same run.

1. The base model (the empty composition, generated like any other) against the simulator
   before the effect mechanism (git revision ``--before``, checked out to a temporary worktree
   and timed in a subprocess in this same run): single torsional and coupled trajectories and a
   256-trajectory torsional batch on one core.  Goal: within 10 %.
2. A model with two effects (motor_lag + the user file examples/effects/string_cubic.py) against
   the base model in the same process.  Goal: within 25 %.
3. Compiling a new composition into an empty kernel cache (a fresh process), then loading it
   from the cache (another fresh process).  Goal: compile <= 30 s, reuse much faster.

    .venv/bin/python benchmarks/bench_effects.py [--duration 30] [--before 19ac81e]

Real-time factor = trajectories x simulated seconds / wall second, best of 5 (dt = 1 ms, RK4,
exact stick, record every 1000th step).  One core (numba threads off for the batch).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CUBIC = f"{ROOT}/examples/effects/string_cubic.py:string_cubic"

TIMER = r"""
import json, sys, time
import numpy as np
from drillgym import simulate_batch
duration, effects = float(sys.argv[1]), json.loads(sys.argv[2])
kw = {"effects": effects["specs"], "effect_params": effects["values"]} if effects["specs"] else {}
def rtf(config, u, dur):
    simulate_batch(config, np.array(u[:1]), 1.0, record_every=1000, **kw)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        simulate_batch(config, np.array(u), dur, record_every=1000, **kw)
        best = min(best, time.perf_counter() - t0)
    return len(u) * dur / best
out = {}
for v in (0.5, 1.5, 2.5, 3.5):
    out[f"torsional single {v} V"] = rtf("torsional", [v], duration)
out["coupled single 2.5 V"] = rtf("coupled", [2.5], duration)
out["torsional batch 256"] = rtf("torsional", list(np.linspace(0.5, 4.5, 256)), duration / 6)
print(json.dumps(out))
"""


def timed(python_path: str, duration: float, specs: list[str], values: dict, cache: str | None = None) -> dict:
    env = dict(os.environ, PYTHONPATH=python_path, NUMBA_NUM_THREADS="1")
    if cache:
        env["DRILLGYM_KERNEL_CACHE"] = cache
    r = subprocess.run(
        [sys.executable, "-c", TIMER, str(duration), json.dumps({"specs": specs, "values": values})],
        capture_output=True,
        text=True,
        env=env,
        cwd=python_path,
    )
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


def compile_time(specs: list[str], cache: str) -> float:
    env = dict(os.environ, PYTHONPATH=str(ROOT), DRILLGYM_KERNEL_CACHE=cache)
    code = (
        "import time, numpy as np; t0 = time.perf_counter(); from drillgym import simulate_batch\n"
        f"simulate_batch('torsional', np.array([1.0]), 0.1, effects={specs!r})\n"
        f"simulate_batch('torsional', np.full(8, 1.0), 0.1, effects={specs!r})\n"
        "print(time.perf_counter() - t0)"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-2000:])
    return float(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0, help="simulated seconds per single trajectory")
    ap.add_argument("--before", default="19ac81e", help="git revision of the simulator before open effects")
    args = ap.parse_args()

    two = {"specs": ["motor_lag", CUBIC], "values": {"tau_m": 0.02, "c3": 0.01}}
    with tempfile.TemporaryDirectory() as tmp:
        wt = Path(tmp) / "before"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(wt), args.before],
            check=True,
            capture_output=True,
        )
        try:
            before = timed(str(wt), args.duration, [], {})
            base = timed(str(ROOT), args.duration, [], {})
            effects = timed(str(ROOT), args.duration, two["specs"], two["values"])
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)], capture_output=True)
        cache = str(Path(tmp) / "fresh-cache")
        t_compile = compile_time(["string_damping", CUBIC], cache)
        t_reuse = compile_time(["string_damping", CUBIC], cache)

    print(f"real-time factor, best of 5, one core; single runs {args.duration:g} s, batch {args.duration / 6:g} s")
    print(f"{'run':<26} {'reference':>10} {'base':>10} {'ratio':>7} {'2 effects':>10} {'ratio':>7}")
    for k in before:
        print(
            f"{k:<26} {before[k]:>9,.0f}x {base[k]:>9,.0f}x {base[k] / before[k]:>7.3f} "
            f"{effects[k]:>9,.0f}x {effects[k] / base[k]:>7.3f}"
        )
    print("goals: base / reference >= 0.90; 2 effects (motor_lag + string_cubic.py) / base >= 0.75")
    print(
        f"new composition (string_damping + string_cubic.py), fresh process: compile + first runs {t_compile:.1f} s "
        f"(goal <= 30 s); again from the cache: {t_reuse:.1f} s"
    )


if __name__ == "__main__":
    main()
