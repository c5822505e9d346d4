"""Hardware link benchmark: round-trip latency and achieved control-period jitter through a real
pseudo-terminal to the rig emulator, at 100 Hz and 500 Hz.

    .venv/bin/python benchmarks/bench_hw.py [--seconds 3]

Round trip: SET_VOLTAGE sent -> SAMPLE received (includes one plant period of simulation in the
emulator).  Jitter: actual send time minus the scheduled tick (Pacer), over the episode.
"""

from __future__ import annotations

import argparse

import numpy as np

from hw.emulator import RigEmulator
from hw.env import HardwareEnv
from hw.runner import ConstantController, run_episode


def bench(rate_hz: float, seconds: float, tmp: str) -> None:
    period = 1.0 / rate_hz
    with RigEmulator("torsional", dt=min(1e-3, period)) as emu:
        env = HardwareEnv(
            emu.port, control_dt=period, episode_duration=seconds, record=f"{tmp}/bench_{rate_hz:.0f}.csv"
        )
        hb = [env.client.heartbeat(k) for k in range(200)]
        res = run_episode(env, controller=ConstantController(2.0), seed=0)
        env.close()
    rt, tick = 1e3 * res.round_trips, 1e3 * res.tick_errors[1:]
    print(
        f"{rate_hz:5.0f} Hz ({res.steps} periods of {1e3 * period:.1f} ms): "
        f"round trip median {np.median(rt):.3f} ms, p99 {np.percentile(rt, 99):.3f} ms, max {rt.max():.3f} ms | "
        f"heartbeat median {1e3 * np.median(hb):.3f} ms | "
        f"tick jitter median {np.median(tick):.3f} ms, p99 {np.percentile(tick, 99):.3f} ms, max {tick.max():.3f} ms, "
        f"std {tick.std():.3f} ms | overruns {env.pacer.overruns}"
    )


if __name__ == "__main__":
    import tempfile

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for rate in (100.0, 500.0):
            bench(rate, args.seconds, tmp)
