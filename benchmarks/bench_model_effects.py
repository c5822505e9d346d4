"""A controller built on a model with an effect, against the same controller without it, on a plant with it.

    .venv/bin/python benchmarks/bench_model_effects.py --effects motor_lag --values tau_m=0.04
    .venv/bin/python benchmarks/bench_model_effects.py --effects input_delay --values delay=0.02
    .venv/bin/python benchmarks/bench_model_effects.py --effects position_friction --values pf_c1=0.15,pf_s1=0.1
    .venv/bin/python benchmarks/bench_model_effects.py --controller lqg-2enc --effects motor_lag,input_delay \\
        --values tau_m=0.04,delay=0.01

Torsional, from rest, nominal base parameters for plant and model, 8000-count encoder; SSI and offset over
the last ``--window`` s of ``--duration`` s runs (controllers.evaluation.metrics), per target.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import controllers
from controllers.evaluation.metrics import run_metrics
from controllers.evaluation.runner import run_closed_loop
from drillgym import Model, RigParams
from drillgym.effects import compose


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controller", default="observer")
    ap.add_argument("--effects", required=True, help="comma-separated effect names")
    ap.add_argument("--values", default="", help="NAME=VALUE,... of the effects' parameters")
    ap.add_argument("--targets", default="1.5,2,2.5,3,4")
    ap.add_argument("--duration", type=float, default=40.0)
    ap.add_argument("--window", type=float, default=15.0)
    a = ap.parse_args()
    values = {k: float(v) for k, v in (item.split("=") for item in a.values.split(",") if item)}
    comp, vals = compose(a.effects.split(","), values)
    model = Model.from_composition(RigParams(), comp, vals)
    tg = np.array([float(v) for v in a.targets.split(",")])
    print(f"plant: {comp.label} {vals}; {a.controller}, targets {tg.tolist()} rad/s, {a.duration:g} s runs")
    for label, m in (("built on the model with its effects", model), ("built on the base model", None)):
        t0 = time.perf_counter()
        ctrl = controllers.make(a.controller, omega_ref=tg, model=m)
        run = run_closed_loop(ctrl, "torsional", tg, a.duration, effects=comp, effect_params=vals)
        met = run_metrics(run, a.window, RigParams())
        print(
            f"{label}: SSI {np.round(met['ssi'], 3).tolist()}, offset {np.round(met['offset'], 3).tolist()} rad/s, "
            f"runaway {bool(met['runaway'].any())} ({time.perf_counter() - t0:.1f} s)"
        )


if __name__ == "__main__":
    main()
