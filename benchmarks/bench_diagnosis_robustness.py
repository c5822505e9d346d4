"""Benchmark: robustness of ``drillgym diagnose`` on recordings unlike the tests'.

A fixed-seed matrix of synthetic recordings
(:func:`drillgym.identification.synthetic.synthetic_measurement`: simulation +
the rig's measurement chain) with ONE hidden effect (or none) is diagnosed
without telling it the effect (the hidden effect is added to the simulated model with
``effects=[name]``; each candidate is tried as a composition, base + candidate).  Varied per recording: the effect
and its magnitude (weak / medium / strong, values below), the effect's *form* (variant
A: the library's form; variant B: a slightly different one the library's
parameters allow: other phases, a second harmonic, the other sign, unequal
asymmetries, delays off the sample grid), the input signal (quasi-random, sum
of sines, random steps, constant voltage), the duration (30/45/60 s), the
sample rate (200/500/1000 Hz), the initial string winding alpha0 and the
configuration (torsional or coupled where the effect acts in both).

Printed: one line per recording, then per effect and magnitude the fraction of
recordings where the true effect ranks first AND is significant ("hit"), where
a wrong effect is significant and first ("wrong"), the false-positive rate on
the no-effect recordings, and the median run time of ``diagnose``.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_diagnosis_robustness.py [--jobs 2] [--json out.json]
        [--only EFFECT] [--limit N]

Magnitudes (weak / medium / strong; physical units):

================== ===================================== ==========================================
effect             variant A (library form)              variant B (other form)
================== ===================================== ==========================================
position_friction  amplitude 0.05/0.12/0.25, random phase + 2nd harmonic of half the amplitude, random
                   (pf_c1 = a cos phi, pf_s1 = a sin phi)   phase (pf_c2, pf_s2)
brake_asymmetry    asym_s = asym_c = 0.1/0.25/0.5        asym_s = m, asym_c = -m/2
string_damping     dtheta 0.002/0.005/0.015 N m s/rad    same (other signals/conditions)
motor_lag          tau_m 0.01/0.03/0.08 s                tau_m x1.3
input_delay        delay 0.007/0.023/0.061 s             0.0113/0.0337/0.087 s (off the sample grid)
lateral_anisotropy dk 80/200/450 N/m, db 1/3/6 N s/m     dk negative, db = 0
lvdt_offset        |offset| 0.1/0.3/1 mm, random angle   same, other angle
lvdt_skew          0.02/0.05/0.12 rad                    negative
lateral_coulomb    Fc_lat 0.3/1/3 N                      same (other conditions)
friction_drift     drift 0.001/0.003/0.007 1/s (linear)  saturating: level 1 + A(1 - exp(-t/15 s)),
                                                         A = +0.04 / -0.1 / +0.25
================== ===================================== ==========================================
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # two worker processes share two cores

import numpy as np  # noqa: E402

SEED = 20261121
MAGS = ("weak", "medium", "strong")
TORS_COUP = ("torsional", "coupled")

# effect -> (configurations, allowed signals, offset range (V) for varying signals)
DESIGN = {
    "position_friction": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps", "constant"), (0.5, 1.5)),
    "brake_asymmetry": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps"), (0.0, 0.0)),
    "string_damping": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps", "constant"), (0.5, 1.5)),
    "motor_lag": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps"), (0.5, 1.5)),
    "input_delay": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps"), (0.5, 1.5)),
    "lateral_anisotropy": (("coupled",), ("quasi_random", "sum_of_sines", "steps", "constant"), (2.5, 3.5)),
    "lvdt_offset": (("coupled",), ("quasi_random", "sum_of_sines", "steps", "constant"), (2.5, 3.5)),
    "lvdt_skew": (("coupled",), ("quasi_random", "sum_of_sines", "steps", "constant"), (2.5, 3.5)),
    "lateral_coulomb": (("coupled",), ("quasi_random", "sum_of_sines", "steps", "constant"), (2.5, 3.5)),
    "friction_drift": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps", "constant"), (0.5, 1.5)),
    "none": (TORS_COUP, ("quasi_random", "sum_of_sines", "steps", "constant"), (0.0, 3.0)),
}
N_NONE = 14


def effect_params(name: str, mag: int, variant: str, rng: np.random.Generator) -> dict[str, float]:
    """Parameters of the hidden effect (see the module docstring)."""
    B = variant == "B"
    if name == "position_friction":
        a1, phi1 = (0.05, 0.12, 0.25)[mag], float(rng.uniform(-np.pi, np.pi))
        out = {"pf_c1": a1 * np.cos(phi1), "pf_s1": a1 * np.sin(phi1)}
        if B:
            phi2 = float(rng.uniform(-np.pi, np.pi))
            out.update(pf_c2=a1 / 2 * np.cos(phi2), pf_s2=a1 / 2 * np.sin(phi2))
        return out
    if name == "brake_asymmetry":
        m = (0.1, 0.25, 0.5)[mag]
        return {"asym_s": m, "asym_c": -m / 2 if B else m}
    if name == "string_damping":
        return {"dtheta": (0.002, 0.005, 0.015)[mag]}
    if name == "motor_lag":
        return {"tau_m": (0.01, 0.03, 0.08)[mag] * (1.3 if B else 1.0)}
    if name == "input_delay":
        return {"delay": ((0.0113, 0.0337, 0.087) if B else (0.007, 0.023, 0.061))[mag]}
    if name == "lateral_anisotropy":
        dk, db = (80.0, 200.0, 450.0)[mag], (1.0, 3.0, 6.0)[mag]
        return {"dk": -dk, "db": 0.0} if B else {"dk": dk, "db": db}
    if name == "lvdt_offset":
        r, a = (1e-4, 3e-4, 1e-3)[mag], float(rng.uniform(0, 2 * np.pi))
        return {"lvdt_x0": r * np.cos(a), "lvdt_y0": r * np.sin(a)}
    if name == "lvdt_skew":
        return {"lvdt_skew": (0.02, 0.05, 0.12)[mag] * (-1 if B else 1)}
    if name == "lateral_coulomb":
        return {"Fc_lat": (0.3, 1.0, 3.0)[mag]}
    if name == "friction_drift":
        if B:  # saturating warm-up/thickening: level 1 + A (1 - exp(-t / T)), T = 15 s
            return {"sat_A": (0.04, -0.1, 0.25)[mag], "sat_T": 15.0}
        return {"drift": (0.001, 0.003, 0.007)[mag]}
    return {}


def build_matrix(seed: int = SEED) -> list[dict]:
    """The recordings (dicts of generation settings), deterministic for a seed."""
    rng = np.random.default_rng(seed)
    cases = []
    for name, (cfgs, sigs, (olo, ohi)) in DESIGN.items():
        combos = [(m, v) for m in range(3) for v in "AB"] if name != "none" else [(-1, "-")] * N_NONE
        for i, (mag, var) in enumerate(combos):
            cfg = cfgs[i % len(cfgs)]
            sig = sigs[int(rng.integers(len(sigs)))]
            if name == "none":
                sig = sigs[i % len(sigs)]
            off = float(rng.uniform(olo, ohi))
            if cfg == "coupled" and name in ("none",):
                off = float(rng.uniform(0.5, 3.0))
            c = {
                "id": len(cases),
                "effect": name,
                "mag": MAGS[mag] if mag >= 0 else "-",
                "variant": var,
                "config": cfg,
                "signal": sig,
                "offset": round(off, 2),
                "duration": float(rng.choice([30.0, 45.0, 60.0])),
                "rate_hz": float(rng.choice([200.0, 500.0, 1000.0])),
                "alpha0": float(rng.choice([0.0, 0.0, 1.5, -3.0, 6.0])),
                "seed": int(rng.integers(1, 10_000)),
                "params": effect_params(name, mag, var, rng),
            }
            if sig == "constant":  # a stick-slip level (brake) or a whirl level (lateral effects)
                c["u"] = round(
                    float(
                        rng.uniform(2.5, 3.5)
                        if cfg == "coupled" and name.startswith(("lat", "lvdt"))
                        else rng.uniform(0.6, 2.5)
                    ),
                    2,
                )
            cases.append(c)
    return cases


def run_case(c: dict) -> dict:
    """Generate one recording, diagnose it, return the outcome."""
    from drillgym.diagnosis import diagnose
    from drillgym.identification.synthetic import synthetic_measurement

    out = dict(c)
    try:
        par = dict(c["params"])
        kw = dict(duration=c["duration"], rate_hz=c["rate_hz"], seed=c["seed"], alpha0=c["alpha0"])
        if "sat_A" in par:
            A, T = par.pop("sat_A"), par.pop("sat_T")
            kw["level_profile"] = lambda t: 1.0 + A * (1.0 - np.exp(-t / T))
        if par:  # the hidden effect, added to the simulated model
            kw.update(effects=[c["effect"]], effect_params=par)
        if c["signal"] == "constant":
            ts = synthetic_measurement(c["config"], u=c["u"], **kw)
        else:
            ts = synthetic_measurement(c["config"], signal=c["signal"], offset=c["offset"], **kw)
        t0 = time.perf_counter()
        d = diagnose(ts)
        out["time_s"] = time.perf_counter() - t0
        out["ranking"] = [(s.effect, round(s.score, 1), round(s.reduction, 3), s.significant) for s in d.ranking]
        out["skipped"] = d.skipped
        out["rmse_before"] = d.rmse_before
        b = d.best
        out["first"] = b.effect if b else None
        out["first_sig"] = bool(b and b.significant)
        out["any_sig"] = [s.effect for s in d.significant()]
        out["error"] = None
    except Exception as exc:  # a crash is a result too
        out.update(
            time_s=float("nan"),
            ranking=[],
            first=None,
            first_sig=False,
            any_sig=[],
            error=f"{type(exc).__name__}: {exc}",
        )
    return out


def verdict(r: dict) -> str:
    if r["error"]:
        return "CRASH"
    if r["effect"] == "none":
        return "FP" if r["any_sig"] else "ok"
    if r["first"] == r["effect"] and r["first_sig"]:
        return "hit"
    if r["first_sig"]:
        return "WRONG"
    return "miss"


def summarise(results: list[dict]) -> str:
    lines = []
    hdr = f"{'effect':<20}{'n':>4}{'hit':>7}{'weak':>7}{'med':>7}{'strong':>8}{'wrong':>7}{'crash':>7}{'med t(s)':>10}"
    lines.append(hdr)
    lines.append("-" * len(hdr))
    tot_hit = tot_n = 0
    for name in DESIGN:
        rs = [r for r in results if r["effect"] == name]
        if not rs:
            continue
        v = [verdict(r) for r in rs]
        ts = [r["time_s"] for r in rs if r["time_s"] == r["time_s"]]
        mt = statistics.median(ts) if ts else float("nan")
        if name == "none":
            fp = sum(x == "FP" for x in v)
            lines.append(
                f"{'none (FP rate)':<20}{len(rs):>4}{fp / len(rs):>7.0%}{'':>7}{'':>7}{'':>8}{'':>7}"
                f"{sum(x == 'CRASH' for x in v):>7}{mt:>10.1f}"
            )
            continue

        def frac(mag: str, rs: list = rs) -> str:
            sub = [verdict(r) for r in rs if r["mag"] == mag]
            return f"{sum(x == 'hit' for x in sub)}/{len(sub)}" if sub else "-"

        hit = sum(x == "hit" for x in v)
        tot_hit, tot_n = tot_hit + hit, tot_n + len(rs)
        lines.append(
            f"{name:<20}{len(rs):>4}{hit / len(rs):>7.0%}{frac('weak'):>7}{frac('medium'):>7}"
            f"{frac('strong'):>8}{sum(x == 'WRONG' for x in v):>7}{sum(x == 'CRASH' for x in v):>7}{mt:>10.1f}"
        )
    if tot_n:
        lines.append(f"{'all effects':<20}{tot_n:>4}{tot_hit / tot_n:>7.0%}")
    ts = [r["time_s"] for r in results if r["time_s"] == r["time_s"]]
    if ts:
        lines.append(f"diagnose time: median {statistics.median(ts):.1f} s, max {max(ts):.1f} s")
    return "\n".join(lines)


def case_line(r: dict) -> str:
    cond = (
        f"{r['config'][:4]} {r['signal'][:8]:<8} {('u=' + str(r['u'])) if 'u' in r else ('o=' + str(r['offset'])):<6} "
        f"{r['duration']:>3.0f}s {r['rate_hz']:>4.0f}Hz a0={r['alpha0']:+.1f}"
    )
    top = ", ".join(f"{e}{'*' if s else ''} {sc:.0f}" for e, sc, _, s in r["ranking"][:3])
    par = ",".join(f"{k}={v:.3g}" for k, v in r["params"].items())
    return (
        f"{r['id']:>3} {verdict(r):<6}{r['effect']:<19}{r['mag']:<7}{r['variant']:<2}{cond}  "
        f"t={r['time_s']:.1f}s  [{par}]  -> {top}{'  ERROR ' + r['error'] if r['error'] else ''}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None, help="write all outcomes to this file")
    ap.add_argument("--only", default=None, help="only recordings of this effect (or 'none')")
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--ids", default=None, help="comma-separated recording ids")
    a = ap.parse_args()
    cases = build_matrix()
    if a.only:
        cases = [c for c in cases if c["effect"] == a.only]
    if a.ids:
        keep = {int(x) for x in a.ids.split(",")}
        cases = [c for c in cases if c["id"] in keep]
    if a.limit:
        cases = cases[: a.limit]
    print(f"{len(cases)} recordings, {a.jobs} processes, seed={SEED}", flush=True)
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        for r in pool.map(run_case, sorted(cases, key=lambda c: -c["duration"])):
            results.append(r)
            print(case_line(r), flush=True)
    results.sort(key=lambda r: r["id"])
    print(f"\nwall time {time.perf_counter() - t0:.0f} s\n")
    print(summarise(results))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1, default=str)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
