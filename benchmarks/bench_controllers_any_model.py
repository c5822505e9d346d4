"""Identify, then control, on plants of an independent simulator with the effects a diagnosis finds.

Each plant (:mod:`independent_rig`: docs/model.md's torsional equations, no drillgym code) has a motor lag, an
input delay and position-dependent brake friction of random sizes, and one of: a drive dead zone, a drive
offset, string damping, changed upper-disc friction, a motor-encoder scale error.  Per plant:

1. the quasi-random excitation (0-5 V at 500 Hz, ``--excitation`` s) through the plant, the encoders
   recorded as the rig reports them, written as a recording (``REC.csv``);
2. ``drillgym diagnose REC.csv --model-out model.json`` (the documented route, a subprocess);
3. ``controllers.make(NAME, omega_ref=TARGETS, model="model.json", counts_per_rev=COUNTS)`` for the observer
   (motor angle only) and lqg-2enc, run from rest on the same plant for ``--duration`` s at 2 ms;
4. SSI and the mean lower speed over the last ``--window`` s: a target is held when SSI < 0.1 and the mean is
   within 10 % of it; the lowest held target is the lowest from which every higher target is held.

Prints one line per plant and controller, then the median and 90th percentile (the higher plant's value) of the
lowest held target, refusals, crashes and runs past 40 rad/s::

    .venv/bin/python benchmarks/bench_controllers_any_model.py --plants 10 --seed 0 --out out/any_model

``--plants-file-out FILE`` writes the same draws as a plants file instead (the effects as drillgym's: the library's
and the files of ``examples/effects``), for ``drillgym evaluate --scenarios plants --plants-file FILE --identify``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from independent_rig import IndependentRig, Plant  # noqa: E402

import controllers  # noqa: E402
from drillgym.io import TimeSeries, write_timeseries  # noqa: E402
from drillgym.signals import quasi_random  # noqa: E402

KINDS = {  # the effect beside the lag, the delay and the position friction: (name, sizes)
    "dead zone": ("u0", (0.2, 0.4)),
    "offset": ("u_off", (0.15, -0.3)),
    "string damping": ("c", (0.01, 0.03)),
    "upper friction": ("tcu_f", (1.3, 0.75)),
    "encoder scale": ("enc_scale", (0.005, -0.01)),
}
DT = 0.002
OVERSPEED = 40.0


def draw_plants(n: int, seed: int, counts: int, noise: float) -> list[tuple[str, Plant]]:
    """n plants cycling through :data:`KINDS` and their sizes, lag, delay and position friction drawn."""
    rng = np.random.default_rng(seed)
    out = []
    kinds = list(KINDS)
    for i in range(n):
        kind = kinds[i % len(kinds)]
        name, sizes = KINDS[kind]
        size = sizes[(i // len(kinds)) % len(sizes)]
        amp, phase = rng.uniform(0.02, 0.12), rng.uniform(0, 2 * np.pi)
        eff = {
            "tau_m": float(rng.uniform(0.01, 0.04)),
            "delay": float(rng.uniform(0.0, 0.012)),
            "pf_c1": float(amp * np.cos(phase)),
            "pf_s1": float(amp * np.sin(phase)),
            name: float(size),
        }
        out.append((f"{kind} {name}={size:g}", Plant(effects=eff, counts=counts, noise=noise)))
    return out


#: each independent effect as the drillgym effect that models it: (spec, {independent name: drillgym parameter})
#: in signal-path order; the effect files are copied beside the plants file
AS_EFFECTS = (
    ("input_delay", {"delay": "delay"}),
    ("effects/motor_dead_zone.py:dead_zone", {"u0": "u0"}),
    ("effects/drive_offset.py:drive_offset", {"u_off": "u_off"}),
    ("motor_lag", {"tau_m": "tau_m"}),
    ("string_damping", {"c": "dtheta"}),
    ("position_friction", {"pf_c1": "pf_c1", "pf_s1": "pf_s1"}),
    ("effects/encoder_scale.py:encoder_scale", {"enc_scale": "enc_scale"}),
)


def write_plants_file(plants: list[tuple[str, Plant]], path: Path) -> Path:
    """The plants as a plants file of ``drillgym evaluate --scenarios plants --plants-file`` (drillgym's simulator
    runs them there: the same plants as drillgym models), the effect files copied into ``effects/`` beside it."""
    import shutil

    import yaml

    examples = Path(__file__).resolve().parent.parent / "examples"
    (path.parent / "effects").mkdir(parents=True, exist_ok=True)
    records = []
    for label, plant in plants:
        effects = []
        for spec, names in AS_EFFECTS:
            values = {p: plant.effects[k] for k, p in names.items() if k in plant.effects}
            if values:
                if spec.startswith("effects/"):
                    shutil.copyfile(examples / spec.split(":")[0], path.parent / spec.split(":")[0])
                effects.append({"spec": spec, "values": values})
        f = plant.value("tcu_f")
        params = {"Tcu": plant.params["Tcu"] * f, "dTcu": plant.params["dTcu"] * f} if f != 1.0 else {}
        record = {
            "name": f"{label} #{len(records)}",
            "effects": effects,
            "encoder": {"counts_per_rev": plant.counts, "angle_noise": plant.noise},
        }
        records.append({**record, **({"params": params} if params else {})})
    path.write_text(yaml.safe_dump({"plants": records}, sort_keys=False))
    return path


def excite(plant: Plant, duration: float, seed: int, path: Path) -> Path:
    """The excitation recording of ``plant`` written to ``path`` (CSV)."""
    t, u = quasi_random(duration, rate_hz=1.0 / DT, seed=seed, amplitude=5.0, offset=2.5)
    rig = IndependentRig([plant], seed=seed)
    cols = {"t": t, "u": u, "theta_u": np.empty(t.size), "theta_l": np.empty(t.size)}
    for k in range(t.size):
        m = rig.measure()
        cols["theta_u"][k], cols["theta_l"][k] = m["theta_u"][0], m["theta_l"][0]
        rig.step(np.array([u[k]]), DT)
    meta = {"configuration": "torsional", "source": "independent_rig", "sample_rate_hz": 1.0 / DT}
    write_timeseries(path, TimeSeries(cols, meta, str(path)))
    return path


def close_loop(ctrl, plant: Plant, targets: np.ndarray, duration: float, window: float, seed: int) -> dict:
    """SSI, mean lower speed over the last ``window`` s and the peak speed of ``ctrl`` on ``plant`` per target."""
    rig = IndependentRig([plant] * targets.size, seed=seed)
    m = rig.measure()
    ctrl.reset({**m, "omega_ref": targets})
    steps = int(round(duration / DT))
    keep = int(round(window / DT))
    wl = np.empty((keep, targets.size))
    peak = np.zeros(targets.size)
    for k in range(steps):
        u = ctrl.act(m)
        rig.step(u, DT)
        m = rig.measure()
        peak = np.maximum(peak, np.maximum(np.abs(rig.omega_l), np.abs(rig.omega_u)))
        if k >= steps - keep:
            wl[k - (steps - keep)] = rig.omega_l
        if np.any(peak > OVERSPEED):  # the rig's over-speed stop
            break
    mean = wl.mean(axis=0)
    ssi = (wl.max(axis=0) - wl.min(axis=0)) / (2 * np.maximum(np.abs(mean), 1e-9))
    held = (ssi < 0.1) & (np.abs(mean - targets) <= 0.1 * targets) & (peak <= OVERSPEED)
    return {"ssi": ssi, "mean": mean, "peak": peak, "held": held}


def lowest_held(targets: np.ndarray, held: np.ndarray) -> float:
    """The lowest target from which every higher target is held (inf: not even the highest)."""
    low = np.inf
    for t, h in sorted(zip(targets, held), reverse=True):
        if not h:
            break
        low = t
    return float(low)


def higher_quantile(values: list[float], q: float) -> float:
    return float(np.quantile(np.asarray(values), q, method="higher"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plants", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--counts", type=int, default=8000, help="encoder counts/rev of every plant")
    ap.add_argument("--noise", type=float, default=2e-4, help="white angle noise of the encoders (rad)")
    ap.add_argument("--controllers", default="observer,lqg-2enc")
    ap.add_argument("--targets", default="1,1.5,2,2.5,3,4")
    ap.add_argument("--excitation", type=float, default=60.0)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--window", type=float, default=20.0)
    ap.add_argument("--out", default="out/any_model")
    ap.add_argument("--reuse", action="store_true", help="take a plant's model.json from --out when it is there")
    ap.add_argument("--identify-only", action="store_true", help="record and diagnose, run no controller")
    ap.add_argument("--first", type=int, default=0, help="start at this plant (the draws stay those of --seed)")
    ap.add_argument(
        "--plants-file-out",
        default=None,
        help="write the drawn plants as a plants file of `drillgym evaluate --plants-file` here and stop",
    )
    a = ap.parse_args()
    if a.plants_file_out:
        print(write_plants_file(draw_plants(a.plants, a.seed, a.counts, a.noise), Path(a.plants_file_out)))
        return
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    targets = np.array([float(v) for v in a.targets.split(",")])
    names = a.controllers.split(",")
    lows: dict[str, list[float]] = {n: [] for n in names}
    problems: list[str] = []
    runaway = dict.fromkeys(names, 0)
    t_all = time.perf_counter()
    for i, (label, plant) in enumerate(draw_plants(a.plants, a.seed, a.counts, a.noise)):
        if i < a.first:
            continue
        t0 = time.perf_counter()
        model = out / f"plant{i}_model.json"
        ok = True
        if not (a.reuse and model.exists()):
            rec = excite(plant, a.excitation, a.seed * 1000 + i, out / f"plant{i}.csv")
            diag = subprocess.run(
                [str(Path(sys.executable).parent / "drillgym"), "diagnose", str(rec), "--model-out", str(model)],
                capture_output=True,
                text=True,
            )
            ok = diag.returncode == 0
        t_id = time.perf_counter() - t0
        if not ok or not model.exists():
            lines = diag.stderr.strip().splitlines() if not ok else []
            why = lines[-1] if lines else "no model file written"
            problems.append(f"plant {i} ({label}): diagnose failed: {why}")
            print(problems[-1], flush=True)
            for n in names:
                lows[n].append(np.inf)
            continue
        effects = [e.get("name") for e in json.loads(model.read_text()).get("effects", [])]
        print(f"plant {i}: {label}, true {plant.effects}; diagnosed {effects} ({t_id:.0f} s)", flush=True)
        for n in [] if a.identify_only else names:
            t1 = time.perf_counter()
            try:
                ctrl = controllers.make(
                    n, omega_ref=targets, model=str(model), counts_per_rev=a.counts, angle_noise=a.noise
                )
                res = close_loop(ctrl, plant, targets, a.duration, a.window, a.seed + i)
            except Exception as exc:  # a refusal or a crash: counted, the other plants go on
                problems.append(f"plant {i} ({label}), {n}: {type(exc).__name__}: {exc}")
                print(problems[-1], flush=True)
                traceback.print_exc(limit=3)
                lows[n].append(np.inf)
                continue
            low = lowest_held(targets, res["held"])
            lows[n].append(low)
            runaway[n] += int(np.any(res["peak"] > OVERSPEED))
            print(
                f"  {n}: lowest held {low:g}; SSI {np.round(res['ssi'], 3).tolist()}, mean "
                f"{np.round(res['mean'], 2).tolist()} ({time.perf_counter() - t1:.0f} s)",
                flush=True,
            )
    if a.identify_only:
        return
    print(f"\n{a.plants} plants, seed {a.seed}, {a.counts} counts, {a.noise:g} rad noise, targets {targets.tolist()}")
    for n in names:
        v = lows[n]
        print(
            f"{n}: lowest held target median {higher_quantile(v, 0.5):g} / 90th pct {higher_quantile(v, 0.9):g} "
            f"(per plant {' / '.join(f'{x:g}' for x in v)}); runs past {OVERSPEED:g} rad/s: {runaway[n]}"
        )
    print(f"refusals and crashes: {len(problems)}" + "".join(f"\n  {p}" for p in problems))
    print(f"wall time {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
