"""Steps per second of the drillgym environments beside Pendulum-v1, measured in the same run.

    .venv/bin/python benchmarks/bench_envs.py [--seconds 2] [--repeats 3]

Single envs are made with ``gymnasium.make`` (same wrappers as Pendulum-v1: order
enforcing + passive checker), stepped with a fixed action and reset when an episode ends.
Vector envs: :func:`drillgym.envs.make_vec` (one batched core call per step), env-steps/s =
N x vector steps/s.  The last rows run compositions of effects (input delay + motor lag; LVDT
offset + skew in the sensors observation).  Each figure is the best of ``--repeats`` timed runs (the machine is shared).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import drillgym  # noqa: F401
from drillgym.envs import make_vec


def single_rate(env: gym.Env, seconds: float) -> float:
    env.reset(seed=0)
    action = np.array([2.0], dtype=np.float32)
    for _ in range(200):  # warm-up (compiled kernels, caches)
        env.step(action)
    n, t0 = 0, time.perf_counter()
    while True:
        for _ in range(1000):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
        n += 1000
        el = time.perf_counter() - t0
        if el >= seconds:
            return n / el


def vector_rate(venv, seconds: float) -> float:
    venv.reset(seed=0)
    actions = np.full((venv.num_envs, 1), 2.0, dtype=np.float32)
    for _ in range(20):
        venv.step(actions)
    n, t0 = 0, time.perf_counter()
    while True:
        for _ in range(10):
            venv.step(actions)
        n += 10
        el = time.perf_counter() - t0
        if el >= seconds:
            return n * venv.num_envs / el


def best(fn, repeats: int) -> float:
    return max(fn() for _ in range(repeats))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=2.0, help="duration of one timed run (s)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per figure (best is kept)")
    args = ap.parse_args()
    s, r = args.seconds, args.repeats

    # Pendulum-v1 and the torsional env alternate, so both see the same machine load
    pend_runs, tors_runs = [], []
    for _ in range(r):
        pend_runs.append(single_rate(gym.make("Pendulum-v1"), s))
        tors_runs.append(single_rate(gym.make("drillgym/Torsional-v0"), s))
    pend, tors = max(pend_runs), max(tors_runs)
    print(f"{'environment':46s} {'steps/s':>12s} {'vs Pendulum-v1':>15s}")
    print(f"{'Pendulum-v1 (gymnasium.make)':46s} {pend:12,.0f} {1.0:15.2f}")
    print(f"{'drillgym/Torsional-v0 [full], 1 env':46s} {tors:12,.0f} {tors / pend:15.2f}")
    for env_id, mode in [
        ("drillgym/Torsional-v0", "sensors"),
        ("drillgym/Torsional-v0", "motor"),
        ("drillgym/Coupled-v0", "full"),
        ("drillgym/Coupled-v0", "sensors"),
        ("drillgym/Coupled-v0", "motor"),
    ]:
        rate = best(lambda env_id=env_id, mode=mode: single_rate(gym.make(env_id, observation=mode), s), r)
        print(f"{env_id + f' [{mode}], 1 env':46s} {rate:12,.0f} {rate / pend:15.2f}")
    for env_id in ("drillgym/Torsional-v0", "drillgym/Coupled-v0"):
        for mode, sizes in (("full", (64, 256)), ("sensors", (256,)), ("motor", (256,))):
            for n in sizes:
                rate = best(
                    lambda env_id=env_id, n=n, mode=mode: vector_rate(make_vec(env_id, n, observation=mode), s), r
                )
                print(f"{env_id + f' [{mode}], vector N={n}':46s} {rate:12,.0f} {rate / pend:15.2f}")
    # a composition of two effects (goal: within 25 % of the base model); its kernels compile once, cached
    two = dict(effects=["input_delay", "motor_lag"], effect_params={"delay": 0.03, "tau_m": 0.02})
    for mode in ("full", "sensors"):
        rate = best(lambda mode=mode: single_rate(gym.make("drillgym/Torsional-v0", observation=mode, **two), s), r)
        print(f"{f'drillgym/Torsional-v0 [{mode}] +delay+lag, 1 env':46s} {rate:12,.0f} {rate / pend:15.2f}")
    rate = best(lambda: vector_rate(make_vec("drillgym/Torsional-v0", 256, **two), s), r)
    print(f"{'drillgym/Torsional-v0 [full] +delay+lag, N=256':46s} {rate:12,.0f} {rate / pend:15.2f}")
    meas = dict(effects=["lvdt_offset", "lvdt_skew"], effect_params={"lvdt_x0": 1e-3, "lvdt_skew": 0.05})
    rate = best(lambda: single_rate(gym.make("drillgym/Coupled-v0", observation="sensors", **meas), s), r)
    print(f"{'drillgym/Coupled-v0 [sensors] +lvdt offset+skew':46s} {rate:12,.0f} {rate / pend:15.2f}")
    pend2 = best(lambda: single_rate(gym.make("Pendulum-v1"), s), r)
    print(f"{'Pendulum-v1 again (load check)':46s} {pend2:12,.0f} {pend2 / pend:15.2f}")
    print(
        f"\ntorsional single env / Pendulum-v1 = {tors / pend:.2f} (target >= 1.0); runs alternated: "
        f"Pendulum {', '.join(f'{x:,.0f}' for x in pend_runs)}; "
        f"torsional {', '.join(f'{x:,.0f}' for x in tors_runs)}"
    )
    print("env step = one 10 ms control period (dt = 10 ms event-driven RK4, exact stick/slip switching)")


if __name__ == "__main__":
    main()
