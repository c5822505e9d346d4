"""Benchmark: full staged identification and one diagnose call on 60 s of 1 kHz data.

Targets (2 cores): staged identification <= 120 s, diagnose <= 60 s.
Data: synthetic measurements (the parameters of docs/model.md; encoder quantization, LVDT
noise and 5 Hz filtering), quasi-random estimation and sum-of-sines
validation signals, 60 s at 1 kHz per recording.  Initial guesses are the
identified values perturbed by 15-30 %.  Prints wall times, recovered-parameter
errors and R² per stage and channel (estimation / validation).

    .venv/bin/python benchmarks/bench_identification.py
"""

from __future__ import annotations

import time

from drillgym import RigParams
from drillgym.diagnosis import diagnose
from drillgym.identification.staged import identify_staged
from drillgym.identification.synthetic import synthetic_measurement

DUR, RATE = 60.0, 1000.0


def main() -> None:
    true = RigParams()
    m = lambda cfg, seed, sig="quasi_random", **kw: synthetic_measurement(  # noqa: E731
        cfg, kw.pop("params", true), duration=kw.pop("duration", DUR), rate_hz=RATE, seed=seed, signal=sig, **kw
    )
    t0 = time.perf_counter()
    est = {
        "upper": m("upper", 1, offset=0.5),
        "free_vibration": m("free_vibration", 1, u=0.0, alpha0=3.0, duration=20.0),
        "lower": m("torsional_bearing", 1, offset=0.5),
        "lateral": m("lateral", 1, offset=3.0),
        "brake": [m("torsional", s, offset=1.0, alpha0=a) for s, a in ((1, 0.0), (2, 2.0), (3, -2.0))],
    }
    val = {
        "upper": m("upper", 2, "sum_of_sines", offset=0.5),
        "lower": m("torsional_bearing", 2, "sum_of_sines", offset=0.5),
        "lateral": m("lateral", 2, "sum_of_sines", offset=3.0),
        "brake": m("torsional", 5, "sum_of_sines", offset=1.0),
    }
    print(f"data generation: {time.perf_counter() - t0:.1f} s")
    start = true.scaled(
        km=1.2,
        Tcu=0.8,
        bu=1.3,
        Jl=1.2,
        bl=0.7,
        Tcl=1.5,
        k=0.8,
        b=1.3,
        e=1.2,
        mt=0.8,
        Ts=1.15,
        Tc=0.85,
        ws=1.2,
        delta=0.9,
        bb=1.3,
    ).replace(dTcu=0.0, dbu=0.0)
    t0 = time.perf_counter()
    res = identify_staged(est, start, validation=val)
    t_id = time.perf_counter() - t0
    print(f"staged identification (5 stages, 7 recordings of {DUR:g} s at {RATE:g} Hz): {t_id:.1f} s (target <= 120 s)")
    for s in res.stages:
        errs = ", ".join(
            f"{k} {100 * (v / getattr(true, k) - 1):+.2f}%"
            for k, v in s.fit.values.items()
            if getattr(true, k) != 0 and not (s.name == "free_vibration")
        )
        r2e = ", ".join(f"{c} {v:.5f}" for c, v in s.r2_estimation.items())
        r2v = ", ".join(f"{c} {v:.5f}" for c, v in s.r2_validation.items())
        print(f"  {s.name:<15} nfev {s.fit.nfev:>3}  R² est [{r2e}]  val [{r2v}]  {errs}")
        for w in s.fit.warnings:
            print(f"    warning: {w}")
    data = m("coupled", 7, offset=3.5, effects=["lateral_anisotropy"], effect_params={"dk": 300.0, "db": 5.0})
    t0 = time.perf_counter()
    d = diagnose(data)
    t_d = time.perf_counter() - t0
    b = d.ranking[0]
    print(
        f"diagnose (coupled, {DUR:g} s at {RATE:g} Hz, hidden lateral_anisotropy, {len(d.ranking)} effects fitted): "
        f"{t_d:.1f} s (target <= 60 s)"
    )
    print(
        f"  first: {b.effect} score {b.score:.1f}, residual RMS {b.rmse_before:.3g} -> {b.rmse_after:.3g} "
        f"({100 * b.reduction:.0f}% cut), fitted {b.values}"
    )
    print(f"  second: {d.ranking[1].effect} score {d.ranking[1].score:.1f}")


if __name__ == "__main__":
    main()
