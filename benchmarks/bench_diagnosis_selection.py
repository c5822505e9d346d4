"""Benchmark: `drillgym diagnose` as model selection, on recordings of an independent rig.

The recordings come from :mod:`bench_diagnosis_rig` (docs/model.md written again for scipy's
``solve_ivp``, smoothed friction, its own measurement chain: NOT drillgym's simulator).  A
fixed-seed matrix varies the input (quasi-random, steps, ramps, sums of sines), the rate
(200 Hz-1 kHz), the duration (20-60 s), the configuration (torsional, coupled), and what the rig
hides:

* ``clean``: nothing (the rig is the model of docs/model.md): nothing may be selected;
* ``mismatch``: base parameters off by 2-8 % (random parameters, random signs), no effect: nothing
  may be selected (the base parameters should be reported as moved);
* ``combo``: two or three library effects at once, half of them with base parameters off by
  2-8 % as well: the selected set must equal the hidden set (a lag/delay swap stated as a tie
  counts separately, and so does a brake asymmetry on a recording whose lower disc never turns
  backward, when the diagnosis states it cannot see one: :func:`unseen`);
* ``outside``: an effect outside the library (ω|ω| brake drag, another Stribeck shape, an upper
  Stribeck bump, a cubic string, free play in the string): the candidate effect file written by
  the diagnosis is fitted (``refit``, as ``identify --add-effect FILE:NAME``) and must at least
  halve the unexplained variance (1 − R² of θl and α).

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/bench_diagnosis_selection.py [--jobs 2] [--json out.json]
        [--kind combo] [--ids 1,2] [--seed N]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

SEED = 20261123
SIGNALS = ("quasi_random", "steps", "ramps", "sum_of_sines")
MISMATCH_PARAMS = ("km", "Tcu", "bu", "ktheta", "Jl", "Ts", "Tc", "ws", "bb")

#: effect combinations (config, {effect: params}); the first four: two effects each, one per kind of pair
COMBOS = [
    ("torsional", {"position_friction": {"pf_c1": 0.12, "pf_s1": -0.08}, "motor_lag": {"tau_m": 0.03}}),
    ("torsional", {"string_damping": {"dtheta": 0.006}, "input_delay": {"delay": 0.03}}),
    ("coupled", {"lateral_anisotropy": {"dk": 250.0, "db": 3.0}, "lvdt_offset": {"lvdt_x0": 4e-4, "lvdt_y0": -2e-4}}),
    ("torsional", {"brake_asymmetry": {"asym_s": 0.3, "asym_c": 0.3}, "friction_drift": {"drift": 0.004}}),
    (
        "torsional",
        {
            "position_friction": {"pf_c1": -0.1, "pf_s1": 0.1},
            "string_damping": {"dtheta": 0.008},
            "motor_lag": {"tau_m": 0.04},
        },
    ),
    ("coupled", {"lvdt_skew": {"lvdt_skew": 0.035}, "lateral_coulomb": {"Fc_lat": 1.5}}),
    (
        "coupled",
        {
            "position_friction": {"pf_c1": 0.15, "pf_s1": 0.0},
            "lvdt_offset": {"lvdt_x0": -3e-4, "lvdt_y0": 3e-4},
            "friction_drift": {"drift": -0.004},
        },
    ),
    ("torsional", {"input_delay": {"delay": 0.05}, "friction_drift": {"drift": 0.005}}),
]
OUTSIDE = [
    ("brake_quadratic", {"cq": 0.004}),
    ("stribeck_shape", {}),
    ("upper_stribeck", {"Tsu": 0.15, "wsu": 0.5}),
    ("string_cubic", {"c3": 0.015}),
    ("string_freeplay", {"gap": 0.1}),
]


DURATIONS = (20.0, 30.0, 45.0, 60.0)

#: library effects a random combination draws from: configurations that can show each, and a draw of its
#: parameters (magnitudes 0.6-1.4x the fixed combinations' values, random signs and phases where the physics
#: allows both)
_RANDOM_EFFECTS: dict[str, tuple[tuple[str, ...], object]] = {
    "position_friction": (
        ("torsional", "coupled"),
        lambda r: (lambda a, ph: {"pf_c1": round(a * math.cos(ph), 4), "pf_s1": round(a * math.sin(ph), 4)})(
            r.uniform(0.08, 0.18), r.uniform(0, 2 * math.pi)
        ),
    ),
    "motor_lag": (("torsional", "coupled"), lambda r: {"tau_m": round(r.uniform(0.02, 0.05), 4)}),
    "input_delay": (("torsional", "coupled"), lambda r: {"delay": round(r.uniform(0.02, 0.05), 4)}),
    "string_damping": (("torsional", "coupled"), lambda r: {"dtheta": round(r.uniform(0.004, 0.01), 4)}),
    "friction_drift": (
        ("torsional", "coupled"),
        lambda r: {"drift": round(r.choice([-1, 1]) * r.uniform(0.003, 0.006), 4)},
    ),
    "brake_asymmetry": (
        ("torsional",),
        lambda r: {"asym_s": round(r.uniform(0.2, 0.4), 3), "asym_c": round(r.uniform(0.2, 0.4), 3)},
    ),
    "lateral_anisotropy": (
        ("coupled",),
        lambda r: {
            "dk": round(r.choice([-1, 1]) * r.uniform(150, 350), 1),
            "db": round(r.choice([-1, 1]) * r.uniform(1.8, 4.2), 2),
        },
    ),
    "lvdt_offset": (
        ("coupled",),
        lambda r: {
            "lvdt_x0": round(r.choice([-1, 1]) * r.uniform(2e-4, 5e-4), 6),
            "lvdt_y0": round(r.choice([-1, 1]) * r.uniform(2e-4, 5e-4), 6),
        },
    ),
    "lvdt_skew": (("coupled",), lambda r: {"lvdt_skew": round(r.choice([-1, 1]) * r.uniform(0.025, 0.045), 4)}),
    "lateral_coulomb": (("coupled",), lambda r: {"Fc_lat": round(r.uniform(1.0, 2.0), 3)}),
}


def random_combos(rng: np.random.Generator, n: int) -> list[tuple[str, dict]]:
    """``n`` combinations of two or three library effects drawn at random (configuration, effects and
    magnitudes), never a motor lag together with an input delay (the stated-tie case of its own)."""
    out = []
    while len(out) < n:
        config = ("torsional", "coupled")[len(out) % 2]
        pool = [e for e, (cfgs, _) in _RANDOM_EFFECTS.items() if config in cfgs]
        names = list(rng.choice(pool, size=int(rng.integers(2, 4)), replace=False))
        if "motor_lag" in names and "input_delay" in names:
            continue
        out.append((config, {str(e): {k: float(v) for k, v in _RANDOM_EFFECTS[str(e)][1](rng).items()} for e in names}))
    return out


def _conditions(rng: np.random.Generator, config: str, effects: dict) -> dict:
    sig = SIGNALS[int(rng.integers(len(SIGNALS)))]
    if "brake_asymmetry" in effects or "string_freeplay" in effects:  # needs reversals (of ωl, of α)
        off, amp = 0.0, 3.0
    elif config == "coupled":
        off, amp = float(rng.uniform(2.3, 3.0)), 1.5
    else:
        off, amp = float(rng.uniform(0.8, 1.5)), 3.0
    return {
        "signal": sig,
        "offset": round(off, 2),
        "amplitude": amp,
        "duration": float(rng.choice(DURATIONS)),
        "rate_hz": float(rng.choice([200.0, 500.0, 1000.0])),
        "seed": int(rng.integers(1, 10_000)),
    }


def _mismatch(rng: np.random.Generator, n: int) -> dict[str, float]:
    names = rng.choice(MISMATCH_PARAMS, size=n, replace=False)
    return {str(k): round(float(1.0 + rng.choice([-1, 1]) * rng.uniform(0.02, 0.08)), 3) for k in names}


def build_matrix(seed: int = SEED, quick: bool = False, random_n: int = 0) -> list[dict]:
    """The recordings; ``quick``: 4 clean, 4 mismatch, each combination once (with base mismatch every
    other one), the 5 outside kinds, durations 20-30 s (a loaded machine).  ``random_n`` > 0: only
    combinations, ``random_n`` of them drawn by :func:`random_combos` (every other one with base mismatch)."""
    global DURATIONS
    DURATIONS = (20.0, 30.0) if quick else (20.0, 30.0, 45.0, 60.0)
    rng = np.random.default_rng(seed)
    cases: list[dict] = []

    def add(kind: str, config: str, effects: dict, scale: dict) -> None:
        c = {"id": len(cases), "kind": kind, "config": config, "effects": effects, "scale": scale}
        c.update(_conditions(rng, config, effects))
        cases.append(c)

    if random_n:
        for i, (cfg, eff) in enumerate(random_combos(np.random.default_rng(seed + 1), random_n)):
            add("combo", cfg, eff, _mismatch(rng, 3) if (i // 2) % 2 else {})  # both configurations either way
        return cases
    n_plain = 4 if quick else 6
    for i in range(n_plain):
        add("clean", ("torsional", "coupled")[i % 2], {}, {})
    for i in range(n_plain):
        add("mismatch", ("torsional", "coupled")[i % 2], {}, _mismatch(rng, 3))
    for i, (cfg, eff) in enumerate(COMBOS):
        if not quick or i % 2 == 0:
            add("combo", cfg, eff, {})
        if not quick or i % 2 == 1:
            add("combo", cfg, eff, _mismatch(rng, 3))
    for name, par in OUTSIDE:
        add("outside", "torsional", {name: par}, {})
    return cases


def run_case(c: dict) -> dict:
    from bench_diagnosis_rig import rig_recording
    from scipy.signal import savgol_filter

    from drillgym.diagnosis import diagnose
    from drillgym.diagnosis.discovery import discover
    from drillgym.diagnosis.refit import refit
    from drillgym.identification.experiment import prepare_experiment

    out = dict(c)
    try:
        ts = rig_recording(
            c["config"],
            c["signal"],
            c["duration"],
            c["rate_hz"],
            c["seed"],
            c["effects"],
            c["scale"],
            c["offset"],
            c["amplitude"],
        )
        t0 = time.perf_counter()
        ex = prepare_experiment(ts, compare_rate_hz=50.0)
        d = diagnose(ex)
        fine = prepare_experiment(ts, compare_rate_hz=min(250.0, c["rate_hz"]))
        with tempfile.TemporaryDirectory() as tmp:
            found, advice = discover(fine, d, Path(tmp) / f"cand{c['id']}.py")
            d = dataclasses.replace(d, candidate=found, advice=advice)
            out["time_s"] = time.perf_counter() - t0
            out["selected"] = list(d.selected)
            out["skipped"] = dict(d.skipped)
            # the recording's own share of backward rotation (θl differentiated here by a 50 ms
            # Savitzky-Golay filter, not the diagnosis' estimate): a brake asymmetry acts only there
            th, dt = np.asarray(ts.columns["theta_l"]), 1.0 / c["rate_hz"]
            wl = savgol_filter(th, 2 * int(0.025 / dt) + 1, 2, deriv=1, delta=dt)
            out["backward_share"] = float(np.mean(wl < -BACKWARD_RAD_S))
            out["ties"] = {s.effect: s.note for s in d.ranking if s.note and s.effect in d.selected}
            out["paths"] = dict(d.paths)
            out["lag_delay"] = d.lag_delay
            out["moved"] = {k: round(v.change_pct, 1) for k, v in d.base_parameters.items()}
            out["rmse"] = (round(d.rmse_before, 1), round(d.rmse_after or 0.0, 1))
            out["candidate"] = d.candidate.expression() if d.candidate else None
            out["explained"] = d.candidate.explained if d.candidate else None
            out["advice"] = d.advice
            if c["kind"] == "outside" and d.candidate is not None:
                r = refit(ts, effects=[d.candidate.effect_file], segment_s=-1.0)
                out["unexplained"] = {ch: (1 - r.r2_before[ch], 1 - r.r2_after[ch]) for ch in ("theta_l", "alpha")}
        out["error"] = None
    except Exception as exc:  # a crash is a result too
        import traceback

        out.update(
            time_s=float("nan"), selected=[], error=f"{type(exc).__name__}: {exc}", trace=traceback.format_exc()[-800:]
        )
    return out


#: pairs the diagnosis may state as a tie (one selected, a note naming the other): a lag and a delay, and a friction
#: that drifts in time and one that depends on the angle (on a recording whose lower disc slides through less than
#: a revolution)
_PAIR = {
    "motor_lag": "input_delay",
    "input_delay": "motor_lag",
    "friction_drift": "position_friction",
    "position_friction": "friction_drift",
}
#: lower-disc speed (rad/s) below which the recording turns backward, and the share of samples under which a
#: brake asymmetry (acting on backward rotation only) is invisible in it
BACKWARD_RAD_S, BACKWARD_SHARE = 0.1, 0.02


def unseen(r: dict) -> set[str]:
    """Hidden effects the recording cannot show, that the diagnosis also stated it cannot see: a brake
    asymmetry when the lower disc turns backward in fewer than BACKWARD_SHARE of the samples (a random
    ramp input that happens to stay positive)."""
    if (
        "brake_asymmetry" in r["effects"]
        and r.get("backward_share", 1.0) < BACKWARD_SHARE
        and "brake_asymmetry" in r.get("skipped", {})
    ):
        return {"brake_asymmetry"}
    return set()


def verdict(r: dict) -> str:
    if r["error"]:
        return "CRASH"
    sel, true = set(r["selected"]), set(r["effects"])
    if r["kind"] in ("clean", "mismatch"):
        return "ok" if not sel else "FALSE"
    if r["kind"] == "combo":
        if sel == true:
            return "right"
        if unseen(r) and sel == true - unseen(r):
            return "unseen"
        ties = r.get("ties", {})
        swapped = {_PAIR[e] if e in _PAIR and _PAIR[e] in ties.get(e, "") else e for e in sel}
        return "tie" if swapped == true else "WRONG"
    u = r.get("unexplained")
    if not u:
        return "none"
    return "halved" if all(a <= 0.5 * b for b, a in u.values()) else "weak"


def case_line(r: dict) -> str:
    cond = f"{r['config'][:4]} {r['signal'][:10]:<10} o={r['offset']:<5} {r['duration']:>3.0f}s {r['rate_hz']:>4.0f}Hz"
    eff = "+".join(r["effects"]) or "-"
    sc = ",".join(f"{k}{(v - 1) * 100:+.0f}%" for k, v in r["scale"].items())
    line = f"{r['id']:>3} {verdict(r):<7}{r['kind']:<9}{cond}  t={r['time_s']:.0f}s  [{eff}] [{sc}] -> {r['selected']}"
    if r.get("moved"):
        line += " base " + ",".join(f"{k}{v:+.1f}%" for k, v in r["moved"].items())
    if r.get("paths"):
        line += " paths " + "; ".join(f"{k}={'+'.join(v) or '-'}" for k, v in r["paths"].items())
    if r.get("lag_delay"):
        ld = r["lag_delay"]
        line += f"; lag_delay_fine={ld['chosen']}:{ld['score_gap_nats']:.1f}nats@{ld['rate_hz']:.0f}Hz"
    if r.get("candidate"):
        line += f" | cand {r['candidate']} ({r['explained']:.0%})"
    if r.get("unexplained"):
        line += " | 1-R² " + ", ".join(f"{k} {b:.2e}->{a:.2e}" for k, (b, a) in r["unexplained"].items())
    if r["error"]:
        line += "  ERROR " + r["error"]
    return line


def summarise(results: list[dict]) -> str:
    v = {r["id"]: verdict(r) for r in results}
    lines = []

    def of(kind: str) -> list[dict]:
        return [r for r in results if r["kind"] == kind]

    cl, mm, co, ou = of("clean"), of("mismatch"), of("combo"), of("outside")
    if cl:
        lines.append(f"clean recordings, nothing selected:        {sum(v[r['id']] == 'ok' for r in cl)}/{len(cl)}")
    if mm:
        lines.append(
            f"base mismatch only, nothing selected:      {sum(v[r['id']] == 'ok' for r in mm)}/{len(mm)}"
            f"   (base parameters reported as moved: {sum(bool(r.get('moved')) for r in mm)}/{len(mm)})"
        )
    if co:
        right = sum(v[r["id"]] == "right" for r in co)
        tie = sum(v[r["id"]] == "tie" for r in co)
        lines.append(
            f"combinations, selected set right:          {right}/{len(co)} ({right / len(co):.0%}); "
            f"with a stated tie: {right + tie}/{len(co)}"
        )
        hidden = sum(v[r["id"]] == "unseen" for r in co)
        if hidden:
            lines.append(
                f"  right but for a hidden effect the recording cannot show (stated as not excited): {hidden}/{len(co)}"
            )
        mmc = [r for r in co if r["scale"]]
        lines.append(f"  of which with base parameters off 2-8 %: {sum(v[r['id']] == 'right' for r in mmc)}/{len(mmc)}")
    if ou:
        lines.append(
            f"outside the library, candidate halves 1-R²: {sum(v[r['id']] == 'halved' for r in ou)}/{len(ou)} kinds"
        )
    ts = [r["time_s"] for r in results if r["time_s"] == r["time_s"]]
    if ts:
        lines.append(f"diagnose time (incl. discovery): median {statistics.median(ts):.1f} s, max {max(ts):.1f} s")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None)
    ap.add_argument("--kind", default=None)
    ap.add_argument("--ids", default=None)
    ap.add_argument("--quick", action="store_true", help="the reduced matrix (21 recordings of 20-30 s)")
    ap.add_argument(
        "--seed",
        type=int,
        default=SEED,
        help=f"seed of the matrix (conditions, mismatch draws, noise); default {SEED}, another one: held out",
    )
    ap.add_argument(
        "--random-combos",
        type=int,
        default=0,
        metavar="N",
        help="instead of the fixed matrix: N combinations of 2-3 library effects drawn at random "
        "(effects, magnitudes, configuration; every other one with base parameters off 2-8 %%)",
    )
    ap.add_argument(
        "--rig-smoothing",
        type=float,
        default=None,
        metavar="EPS",
        help="the independent rig's friction smoothing tanh(w/EPS) (rad/s; default "
        "bench_diagnosis_rig.EPS): how much its discs creep while stuck",
    )
    a = ap.parse_args()
    if a.rig_smoothing is not None:
        if not a.rig_smoothing > 0:
            raise SystemExit(f"--rig-smoothing must be > 0 rad/s, got {a.rig_smoothing}")
        os.environ["DRILLGYM_BENCH_RIG_EPS"] = repr(a.rig_smoothing)  # the worker processes read it
    cases = build_matrix(seed=a.seed, quick=a.quick, random_n=a.random_combos)
    if a.kind:
        cases = [c for c in cases if c["kind"] == a.kind]
    if a.ids:
        keep = {int(x) for x in a.ids.split(",")}
        cases = [c for c in cases if c["id"] in keep]
    what = " (random combinations)" if a.random_combos else " (quick matrix)" if a.quick else ""
    import bench_diagnosis_rig

    print(
        f"{len(cases)} recordings of the independent rig{what}, {a.jobs} processes, "
        f"seed={a.seed}, rig friction smoothing {bench_diagnosis_rig.rig_eps() * 1e3:g} mrad/s",
        flush=True,
    )
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        for r in pool.map(run_case, sorted(cases, key=lambda c: -c["duration"])):
            results.append(r)
            print(case_line(r), flush=True)
            if r.get("trace"):
                print(r["trace"], flush=True)
    results.sort(key=lambda r: r["id"])
    print(f"\nwall time {time.perf_counter() - t0:.0f} s\n")
    print(summarise(results))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as fh:
            json.dump(results, fh, indent=1, default=str)


if __name__ == "__main__":
    main()
