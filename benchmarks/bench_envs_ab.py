"""Env speed of this checkout against another one (e.g. before a rewrite), measured alternately.

    .venv/bin/python benchmarks/bench_envs_ab.py --other /work/old [--seconds 0.5] [--rounds 7]

On a shared machine the load changes by several times within a minute, so two benchmark runs one
after the other compare nothing.  Here one worker process per checkout (each importing its own
drillgym) stays alive and the driver alternates them figure by figure, round by round: both see
the same load.  Reported per figure: the best of the rounds (the least disturbed) for each
checkout and their ratio.  Rows with effects (options the other checkout lacks) alternate instead
with the same env of this checkout without effects: the ratio is then the cost of the effects.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve()

#: (label, env id, options, vector size or 0, in the other checkout too)
FIGURES = [
    ("Pendulum-v1 (load reference)", "Pendulum-v1", {}, 0, True),
    ("Torsional [full], 1 env", "drillgym/Torsional-v0", {}, 0, True),
    ("Torsional [sensors], 1 env", "drillgym/Torsional-v0", {"observation": "sensors"}, 0, True),
    ("Torsional [motor], 1 env", "drillgym/Torsional-v0", {"observation": "motor"}, 0, True),
    ("Coupled [full], 1 env", "drillgym/Coupled-v0", {}, 0, True),
    ("Coupled [sensors], 1 env", "drillgym/Coupled-v0", {"observation": "sensors"}, 0, True),
    ("Torsional [full], N=256", "drillgym/Torsional-v0", {}, 256, True),
    ("Torsional [sensors], N=256", "drillgym/Torsional-v0", {"observation": "sensors"}, 256, True),
    ("Coupled [full], N=256", "drillgym/Coupled-v0", {}, 256, True),
    (
        "Torsional [full] +delay+lag, 1 env",
        "drillgym/Torsional-v0",
        {"effects": ["input_delay", "motor_lag"], "effect_params": {"delay": 0.03, "tau_m": 0.02}},
        0,
        False,
    ),
    (
        "Torsional [full] +delay+lag, N=256",
        "drillgym/Torsional-v0",
        {"effects": ["input_delay", "motor_lag"], "effect_params": {"delay": 0.03, "tau_m": 0.02}},
        256,
        False,
    ),
    (
        "Coupled [sensors] +lvdt offset+skew, 1 env",
        "drillgym/Coupled-v0",
        {
            "observation": "sensors",
            "effects": ["lvdt_offset", "lvdt_skew"],
            "effect_params": {"lvdt_x0": 1e-3, "lvdt_skew": 0.05},
        },
        0,
        False,
    ),
]


def worker() -> None:
    """Measure figures on request (one JSON line in, one rate out), envs kept between requests."""
    import time

    import gymnasium as gym
    import numpy as np

    import drillgym  # noqa: F401
    from drillgym.envs import make_vec

    envs = {}
    for line in sys.stdin:
        env_id, opts, n, seconds = json.loads(line)
        key = json.dumps([env_id, opts, n], sort_keys=True)
        if key not in envs:
            env = make_vec(env_id, n, **opts) if n else gym.make(env_id, **opts)
            env.reset(seed=0)
            envs[key] = env
        env = envs[key]
        act = np.full((n, 1), 2.0, dtype=np.float32) if n else np.array([2.0], dtype=np.float32)
        for _ in range(50):  # warm-up
            out = env.step(act)
            if not n and (out[2] or out[3]):
                env.reset()
        k, t0 = 0, time.perf_counter()
        while True:
            for _ in range(100):
                out = env.step(act)
                if not n and (out[2] or out[3]):
                    env.reset()
            k += 100
            el = time.perf_counter() - t0
            if el >= seconds:
                break
        print(k * max(n, 1) / el, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--other", required=True, help="root of the other checkout (its drillgym is imported there)")
    ap.add_argument("--seconds", type=float, default=0.5, help="duration of one timed run (s)")
    ap.add_argument("--rounds", type=int, default=7, help="alternating rounds per figure")
    args = ap.parse_args()
    roots = {"this": HERE.parents[1], "other": Path(args.other).resolve()}
    procs = {}
    for name, root in roots.items():
        env = dict(os.environ, PYTHONPATH=str(root))
        procs[name] = subprocess.Popen(
            [sys.executable, str(HERE), "--worker"],
            cwd=root,
            env=env,
            text=True,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )

    def measure(name: str, env_id: str, opts: dict, n: int) -> float:
        p = procs[name]
        p.stdin.write(json.dumps([env_id, opts, n, args.seconds]) + "\n")
        p.stdin.flush()
        line = p.stdout.readline()
        if not line:
            raise RuntimeError(f"worker of {roots[name]} died (see its stderr above)")
        return float(line)

    print(f"{'figure (env-steps/s, best of ' + str(args.rounds) + ')':46s} {'this':>12s} {'other':>12s} {'ratio':>7s}")
    try:
        for label, env_id, opts, n, both in FIGURES:
            runs = {"this": [], "ref": []}
            base = {k: v for k, v in opts.items() if k not in ("effects", "effect_params")}
            for _ in range(args.rounds):
                runs["this"].append(measure("this", env_id, opts, n))
                runs["ref"].append(measure("other", env_id, opts, n) if both else measure("this", env_id, base, n))
            a, b = max(runs["this"]), max(runs["ref"])
            ref = f"{b:12,.0f}" if both else f"{b:>,.0f} (this, no effect)"
            print(f"{label:46s} {a:12,.0f} {ref:>12s} {a / b:7.2f}", flush=True)
    finally:
        for p in procs.values():
            p.stdin.close()
            p.wait(timeout=60)


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker()
    else:
        main()
