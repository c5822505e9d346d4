"""lqg-2enc on coarse encoders: the default design against the one told the encoders' resolution.

    .venv/bin/python benchmarks/bench_coarse_encoders.py --counts 2048 --noise 5e-4

Nominal plant and model, torsional, from rest, ``--duration`` s at 2 ms judged on the last ``--window`` s
(controllers.evaluation.metrics); prints SSI and the mean's offset per target for each design.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import controllers
from controllers.evaluation.metrics import run_metrics
from controllers.evaluation.runner import run_closed_loop
from controllers.two_encoder import TwoEncoderDesign
from drillgym import RigParams


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, default=2048)
    ap.add_argument("--noise", type=float, default=5e-4, help="white angle noise (rad)")
    ap.add_argument("--targets", default="0.5,0.75,1,1.25,1.4,1.5,1.6,1.75,2,3,5")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--window", type=float, default=20.0)
    a = ap.parse_args()
    tg = np.array([float(v) for v in a.targets.split(",")])
    designs = {
        "default (4096 counts assumed)": {},
        "dead band alone": {"design": TwoEncoderDesign(counts=a.counts, dead_band=0.7)},
        "noise alone (3 mrad floor)": {"design": TwoEncoderDesign(counts=a.counts, noise_floor=3e-3)},
        "told the resolution": {"counts_per_rev": a.counts, "angle_noise": a.noise},
    }
    print(f"{a.counts} counts, {a.noise:g} rad noise, targets {tg.tolist()} rad/s")
    for label, kw in designs.items():
        t0 = time.perf_counter()
        ctrl = controllers.make("lqg-2enc", omega_ref=tg, **kw)
        run = run_closed_loop(ctrl, "torsional", tg, a.duration, counts_per_rev=a.counts, angle_noise=a.noise)
        met = run_metrics(run, a.window, RigParams())
        print(
            f"{label}: SSI {np.round(met['ssi'], 3).tolist()}, offset {np.round(met['offset'], 3).tolist()} rad/s "
            f"({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
