"""How long one `drillgym diagnose` takes on 60 s of 1 kHz data (the goal: within 60 s on 2 cores).

Three recordings of 60 s at 1 kHz, each diagnosed by the command line as a user runs it (a fresh
process: import, kernels loaded from the on-disk cache, model selection with the base model
decision, discovery of a candidate beyond the library), twice: the first call may compile the
kernels of compositions no earlier call used, the second shows the steady cost.

1. torsional, quasi-random input, no effect, base parameters off by a few percent;
2. torsional, steps, position_friction + motor_lag, base parameters off;
3. coupled, sum of sines, lateral_anisotropy + lvdt_offset;
4. the independent rig of ``bench_diagnosis_rig`` (not drillgym's simulator), coupled, ramps, three
   effects (position_friction + lvdt_offset + friction_drift), base parameters off by 4-5 %: the
   slowest kind of the selection benchmark's matrix.

``--motor``: instead, recordings of the independent motor rig of ``bench_diagnosis_motor`` (effects outside
the library on the motor side, each after a motor lag, base parameters off; :data:`MOTOR_CASES`), where the
candidate's own fit and the whole library selected again with the candidate in the model run too.

``--identify``: run the identification route instead (``drillgym diagnose FILE --json --model-out M.json``:
:func:`drillgym.identify`, the library selected again beside a kept candidate and the joint refit included),
the time the goal of 60 s is about for a model file.

``--combos``: instead, random combinations of the selection benchmark's matrix
(``bench_diagnosis_selection.build_matrix(seed, random_n=16)``, case ``i``; recordings of the
independent rig, 2-3 effects, base parameters off in some) made 60 s long at 1 kHz, each diagnosed once,
with the verdict of that benchmark (right / a stated lag-delay tie / WRONG).  ``--combos default``: six
combinations, four of them coupled (:data:`DEFAULT_COMBOS`), the set of the documented timing table.

    .venv/bin/python benchmarks/bench_diagnose_time.py [--out DIR] [--motor] [--identify]
        [--combos default|SEED:I,...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from drillgym import RigParams
from drillgym.identification.synthetic import synthetic_measurement
from drillgym.io import write_timeseries

DUR, RATE = 60.0, 1000.0
OFF = RigParams().scaled(km=0.97, Ts=1.06, Jl=1.04)  # a base model a few percent off

CASES = {
    "torsional, no effect, base off": dict(config="torsional", params=OFF, signal="quasi_random", offset=1.0, seed=3),
    "torsional, position_friction + motor_lag, base off": dict(
        config="torsional",
        params=OFF,
        signal="steps",
        offset=1.2,
        seed=4,
        effects=["position_friction", "motor_lag"],
        effect_params={"pf_c1": 0.12, "pf_s1": 0.08, "tau_m": 0.04},
    ),
    "coupled, lateral_anisotropy + lvdt_offset": dict(
        config="coupled",
        signal="sum_of_sines",
        offset=3.0,
        seed=5,
        effects=["lateral_anisotropy", "lvdt_offset"],
        effect_params={"dk": 250.0, "db": 3.0, "lvdt_x0": 3e-4},
    ),
}
RIG_CASES = {
    "independent rig, coupled, three effects, base off": dict(
        config="coupled",
        signal="ramps",
        offset=2.66,
        amplitude=1.5,
        seed=2576,
        effects={
            "position_friction": {"pf_c1": 0.15, "pf_s1": 0.0},
            "lvdt_offset": {"lvdt_x0": -3e-4, "lvdt_y0": 3e-4},
            "friction_drift": {"drift": -0.004},
        },
        scale={"Ts": 1.037, "bu": 0.955, "Jl": 1.053},
    ),
}

#: motor-side recordings (``bench_diagnosis_motor.motor_recording``): effect parameters and base scales
MOTOR_CASES = {
    "motor rig, dead zone 0.4 V + lag 30 ms, steps, base off": dict(
        signal="steps",
        seed=11,
        effects={"dead_zone": {"u0": 0.4}, "motor_lag": {"tau_m": 0.03}},
        scale={"km": 0.97, "Ts": 1.04, "Jl": 1.03},
    ),
    "motor rig, cogging 0.12 N m + lag 35 ms, quasi-random, base off": dict(
        signal="quasi_random",
        seed=12,
        effects={"cogging": {"Tcog": 0.12, "phase": 1.0}, "motor_lag": {"tau_m": 0.035}},
        scale={"km": 1.03, "bu": 0.96, "ktheta": 1.02},
    ),
    "motor rig, voltage offset 0.15 V + lag 25 ms, ramps, base off": dict(
        signal="ramps",
        seed=13,
        effects={"voltage_offset": {"u_off": 0.15}, "motor_lag": {"tau_m": 0.025}},
        scale={"km": 0.98, "Tc": 1.04, "Jl": 0.97},
    ),
}


def _motor(out: Path) -> None:
    """Time two diagnoses of each motor-side recording (:data:`MOTOR_CASES`)."""
    from bench_diagnosis_motor import motor_recording

    for i, (name, kw) in enumerate(MOTOR_CASES.items()):
        ts = motor_recording(kw["signal"], DUR, RATE, kw["seed"], kw["effects"], kw["scale"])
        path = write_timeseries(out / f"motor{i}.csv", ts)
        first, res = _diagnose(path)
        second, _ = _diagnose(path)
        cand = res.get("candidate") or {}
        fit = cand.get("fit") or {}
        again = res.get("reselection") or {}
        print(
            f"  {name:<64} first {first:6.1f} s, second {second:6.1f} s (goal <= 60 s); "
            f"selected {res['selected']}; candidate {cand.get('group')} cut {fit.get('variance_cut')}; "
            f"selected again beside it {again.get('selected')}"
        )


#: with ``--identify``: the model file each diagnosis writes (the identification route)
IDENTIFY = {"on": False}


def _diagnose(path: Path) -> tuple[float, dict]:
    model_out = ["--model-out", str(path.with_suffix(".model.json"))] if IDENTIFY["on"] else []
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", "diagnose", str(path), "--json", *model_out],
        capture_output=True,
        text=True,
        check=True,
    )
    wall = time.perf_counter() - t0
    return wall, json.loads(p.stdout[p.stdout.index("{") :])


#: the default random combinations, SEED:I (the matrix seed, the case's index): four coupled, two torsional
DEFAULT_COMBOS = "1616:3,404:5,606:7,1818:2,1818:9,1919:4"


def _combos(spec: str, out: Path) -> None:
    """Time one diagnose per random combination SEED:I made 60 s long at 1 kHz; print the verdict."""
    from bench_diagnosis_rig import rig_recording
    from bench_diagnosis_selection import build_matrix, verdict

    total = 0.0
    for item in (DEFAULT_COMBOS if spec == "default" else spec).split(","):
        seed, i = (int(x) for x in item.split(":"))
        c = dict(build_matrix(seed=seed, random_n=16)[i], duration=DUR, rate_hz=RATE)
        ts = rig_recording(
            c["config"], c["signal"], DUR, RATE, c["seed"], c["effects"], c["scale"], c["offset"], c["amplitude"]
        )
        effects = "+".join(sorted(c["effects"])) or "none"
        path = write_timeseries(out / f"{c['config']}_{effects}_{c['signal']}_60s_1000Hz.csv", ts)
        wall, res = _diagnose(path)
        total += wall
        # as the selection benchmark: a selected effect with a note (a stated tie) may be its lag/delay partner
        ties = {
            s["effect"]: s["note"] for s in res.get("ranking", []) if s.get("note") and s["effect"] in res["selected"]
        }
        v = verdict({**c, "error": None, "selected": res["selected"], "ties": ties})
        print(
            f"  {c['config']:<9} {c['signal']:<12} {wall:6.1f} s (goal <= 60 s)  {v:<5} "
            f"true {sorted(c['effects'])} -> {res['selected']}"
        )
    print(f"  total {total:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="keep the recordings here (default: a temporary dir)")
    ap.add_argument(
        "--combos",
        default=None,
        help="time random combinations SEED:I,... made 60 s long ('default': six); see the module docstring",
    )
    ap.add_argument("--motor", action="store_true", help="time motor-side recordings instead (see the docstring)")
    ap.add_argument("--identify", action="store_true", help="time `diagnose --model-out` (the identification)")
    args = ap.parse_args()
    IDENTIFY["on"] = args.identify
    out = args.out or Path(tempfile.mkdtemp(prefix="bench_diagnose_"))
    out.mkdir(parents=True, exist_ok=True)
    print(
        f"{DUR:g} s at {RATE:g} Hz per recording; `drillgym diagnose FILE --json` in a fresh process; "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}"
    )
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_diagnosis_rig import rig_recording

    if args.combos:
        _combos(args.combos, out)
        return
    if args.motor:
        _motor(out)
        return
    recordings = {
        name: synthetic_measurement(
            kw["config"],
            kw.get("params"),
            duration=DUR,
            rate_hz=RATE,
            **{k: v for k, v in kw.items() if k not in ("config", "params")},
        )
        for name, kw in CASES.items()
    }
    recordings.update(
        {
            name: rig_recording(
                kw["config"],
                kw["signal"],
                DUR,
                RATE,
                kw["seed"],
                kw["effects"],
                kw["scale"],
                kw["offset"],
                kw["amplitude"],
            )
            for name, kw in RIG_CASES.items()
        }
    )
    for i, (name, ts) in enumerate(recordings.items()):
        path = write_timeseries(out / f"rec{i}.csv", ts)
        first, res = _diagnose(path)
        second, _ = _diagnose(path)
        moved = ", ".join(f"{k} {v['change_pct']:+.1f}%" for k, v in res.get("base_parameters", {}).items())
        print(
            f"  {name:<52} first {first:6.1f} s, second {second:6.1f} s (goal <= 60 s); "
            f"selected {res['selected']}; base moved: {moved or 'none'}"
        )


if __name__ == "__main__":
    main()
