"""Must-show matrix of :func:`drillgym.identify`: an effect outside the library with a library effect beside it.

Recordings come from the independent scipy rig of ``bench_diagnosis_motor.py`` (the model page written again by
hand, smoothed friction, LSODA, its own measurement chain): one motor-side effect outside drillgym's library
(``dead_zone``, ``voltage_offset``, ``saturation``, ``cogging``, ``backlash``: see that script) and one library
effect beside it (the companion: ``motor_lag`` 20-40 ms, ``input_delay`` 15-30 ms, ``position_friction``
5-12 % first harmonic, ``string_damping`` 2-5e-3 N m s/rad, ``brake_asymmetry`` 15-30 %), on steps, ramps or
quasi-random input (cycled), base parameters 0-5 % off.  Each recording is identified as every route does
(``drillgym.identify``: diagnosis, discovery, the library selected again beside a kept candidate, one joint
refit), and the model it gives is compared with the recording as ``compare REC --model`` does (segments of
the configuration's default length).  Reported per companion and overall:

* ``companion_found_where_shown``: among the recordings that can show the companion (the diagnosis did not
  skip it, e.g. a brake asymmetry where the lower disc never turns backwards), the share whose identified model
  holds it, or its partner in a lag/delay tie the selection states;
* ``halved``: the share where the candidate's own fit at least halves the unexplained variance;
* ``within_3x``: the share where the model file leaves the residual within 3x the noise on every channel;
* ``within_3x_or_exact``: or within what the rig's exact model leaves (``exact_to_noise``: its own base parameters
  and effects, the outside ones as the effect files of ``benchmarks/effects/motor_side.py`` and ``examples/``, run by
  drillgym and compared the same way; none for the backlash): the floor of the comparison on that recording;
* ``silent``: recordings left at >= 10x the noise that are reported as explained (must be 0);
* ``wrong_library``: the library effects in the model the rig does not have (a lag for the rig's delay, or the
  converse, is not counted: the selection states where it cannot tell them apart).

    python benchmarks/bench_identify_companions.py [--config torsional] [--seeds 1] [--first-seed 0] [--limit N]
        [--duration 20] [--outside motor|sensors] [--out results.jsonl]

``--outside sensors`` puts encoders that read off the truth in the outside effect's place
(``bench_diagnosis_rig.OUTSIDE_READING``: the motor's or the lower's counts per revolution 0.3-2 % off, the lower's
zero 5-30 mrad off the motor's), read by drillgym as ``benchmarks/effects/sensors.py`` and
``examples/effects/encoder_scale.py``.

``--config coupled`` records the coupled independent rig (``bench_diagnosis_rig``) with the same motor-side
effects (no backlash: its rotor is modelled on the torsional rig only) and compares the LVDT channels too.

The draws of a seed were never used to tune drillgym; run fresh ones with ``--first-seed``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_diagnosis_motor import MISMATCHED, SIGNALS, MotorRig, draw, motor_recording  # noqa: E402
from bench_diagnosis_rig import rig_recording  # noqa: E402

OUTSIDE = ("dead_zone", "voltage_offset", "saturation", "cogging", "backlash")
#: on the coupled rig (the independent rig's backlash has its rotor on the torsional rig only)
OUTSIDE_COUPLED = OUTSIDE[:4]
#: ``--outside sensors``: encoders that read off the truth (``bench_diagnosis_rig.OUTSIDE_READING``)
SENSORS = ("motor_encoder_scale", "lower_encoder_scale", "lower_encoder_offset")
COMPANIONS = ("motor_lag", "input_delay", "position_friction", "string_damping", "brake_asymmetry")


def draw_companion(name: str, rng: np.random.Generator) -> dict[str, float]:
    """The library effect's values (the independent rig's names)."""
    if name == "motor_lag":
        return {"tau_m": float(rng.uniform(0.02, 0.04))}
    if name == "input_delay":
        return {"delay": float(rng.uniform(0.015, 0.03))}
    if name == "position_friction":
        a, ph = float(rng.uniform(0.05, 0.12)), float(rng.uniform(0, 2 * math.pi))
        return {"pf_c1": a * math.cos(ph), "pf_s1": a * math.sin(ph)}
    if name == "string_damping":
        return {"dtheta": float(rng.uniform(2e-3, 5e-3))}
    return {"asym_s": float(rng.uniform(0.15, 0.3)), "asym_c": float(rng.uniform(0.15, 0.3))}


def rows(seeds: int, first_seed: int, config: str = "torsional", outside: tuple[str, ...] | None = None) -> list[dict]:
    """Every companion beside an outside effect (the outside kind cycles over ``outside``: default the motor side's
    of the configuration), per seed."""
    outside = outside or (OUTSIDE if config == "torsional" else OUTSIDE_COUPLED)
    out = []
    for seed in range(first_seed, first_seed + seeds):
        for i, companion in enumerate(COMPANIONS):
            rng = np.random.default_rng(90_000 + 131 * seed + i)
            kind = outside[(i + seed) % len(outside)]
            effects = {kind: draw(kind, rng), companion: draw_companion(companion, rng)}
            scale = {k: float(1.0 + rng.uniform(-0.05, 0.05)) for k in MISMATCHED}
            signal = SIGNALS[(i + 2 * seed) % len(SIGNALS)]
            out.append(
                {"kind": kind, "companion": companion, "signal": signal, "seed": 50 * seed + i, "config": config}
                | {"effects": effects, "scale": scale}
            )
    return out


def recording(row: dict, duration: float, rate_hz: float):
    """The row's recording: the torsional rig of ``bench_diagnosis_motor``, or the coupled independent rig with the
    same motor-side effects (its LVDTs too)."""
    args = (row["signal"], duration, rate_hz, row["seed"], row["effects"], row["scale"])
    if row["config"] == "torsional":
        return motor_recording(*args)
    # the coupled matrices' excitation (bench_diagnosis_selection): turning clear of the lateral resonance, or
    # about zero where a brake asymmetry needs the lower disc to turn backwards
    offset, amplitude = (0.0, 3.0) if row["companion"] == "brake_asymmetry" else (2.6, 1.5)
    return rig_recording("coupled", *args, offset=offset, amplitude=amplitude, rig_class=MotorRig)


#: the outside effects as drillgym effect files (the exact model; the backlash's rotor has none)
HERE = Path(__file__).resolve().parent
OUTSIDE_FILES = {
    "dead_zone": f"{HERE.parent / 'examples/effects/motor_dead_zone.py'}:dead_zone",
    "voltage_offset": f"{HERE.parent / 'examples/effects/drive_offset.py'}:drive_offset",
    "saturation": f"{HERE / 'effects/motor_side.py'}:saturation",
    "cogging": f"{HERE / 'effects/motor_side.py'}:cogging",
    "motor_encoder_scale": f"{HERE.parent / 'examples/effects/encoder_scale.py'}:encoder_scale",
    "lower_encoder_scale": f"{HERE / 'effects/sensors.py'}:lower_encoder_scale",
    "lower_encoder_offset": f"{HERE / 'effects/sensors.py'}:lower_encoder_offset",
}
#: the timing companions come before the motor-side effect on the signal path (the motor sees f(u_m))
TIMING = ("input_delay", "motor_lag")


def exact_model(row: dict):
    """The rig's own model run by drillgym: its base parameters, the companion and the outside effect at the values
    drawn (None for the backlash: a degree of freedom no effect file here has)."""
    from drillgym import Model, RigParams

    kind, companion = row["kind"], row["companion"]
    if kind not in OUTSIDE_FILES:
        return None
    outside = OUTSIDE_FILES[kind]
    specs = [companion, outside] if companion in TIMING else [outside, companion]
    values = {**row["effects"][kind], **row["effects"][companion]}
    return Model(RigParams().scaled(**row["scale"]), tuple(specs), values)


def run_row(row: dict, duration: float, rate_hz: float, work: Path) -> dict:
    """Identify one recording and compare its model with it."""
    from drillgym import identify
    from drillgym.diagnosis.model_compare import compare_models
    from drillgym.diagnosis.screening import default_segment
    from drillgym.identification.experiment import prepare_experiment

    ts = recording(row, duration, rate_hz)
    t0 = time.perf_counter()
    found = identify(ts, candidate_out=work / f"cand_{row['seed']}.py")
    seconds = time.perf_counter() - t0
    ex = prepare_experiment(ts, compare_rate_hz=100.0)
    mc = compare_models(ex, found.model, segment_s=default_segment(ex.config))
    ratios = mc.ratios(mc.model)
    exact = exact_model(row)
    floor = None
    if exact is not None:
        ex_mc = compare_models(ex, exact, segment_s=default_segment(ex.config))
        floor = ex_mc.ratios(ex_mc.model)
    d = found.diagnosis
    # the candidate kept first (a library effect discovery named in its place takes no turn: then the next one's)
    fits = [s.candidate.fit for s in d.in_turn() if s.candidate is not None and s.candidate.fit is not None]
    fit = fits[0] if fits else None
    last = found.reselection or d
    un = last.unexplained
    # a lag and a delay the selection states it cannot tell apart on this input count as the other one
    tie = any(s.effect in found.model.names and row["companion"] in s.note for s in last.ranking) or any(
        " is held in the model, not decided against " + row["companion"] in w for w in last.warnings
    )
    not_shown = last.skipped.get(row["companion"]) if row["companion"] not in found.model.names else None
    return {
        **{k: row[k] for k in ("config", "kind", "companion", "signal", "seed")},
        "hidden": row["effects"],
        "model": found.model.names,
        "values": dict(found.model.values),
        "first_selection": list(d.selected),
        "companion_found": row["companion"] in found.model.names or tie,
        "stated_tie": tie,
        "not_shown": not_shown,
        "candidate": list(found.discovered),
        "candidate_cut": fit.variance_cut if fit is not None else None,
        "halved": bool(fit is not None and fit.variance_cut >= 0.5),
        "model_to_noise": ratios,
        "within_3x": bool(all(v <= 3.0 for v in ratios.values() if np.isfinite(v))),
        "exact_to_noise": floor,
        "within_3x_or_exact": bool(
            all(v <= max(3.0, (floor or {}).get(c, 0.0)) for c, v in ratios.items() if np.isfinite(v))
        ),
        "silent": bool(un is not None and un.worst >= 10.0 and un.explained),
        "wrong_library": wrong_library(found.model.names, row["effects"]),
        "seconds": seconds,
    }


def wrong_library(model: tuple[str, ...] | list[str], hidden: dict) -> list[str]:
    """The library effects in the model that the rig does not have (a motor lag for the rig's input delay, or the
    converse, is the other timing effect, not a wrong one)."""
    from drillgym.effects import LIBRARY

    timing = any(t in hidden for t in TIMING)
    return [n for n in model if n in LIBRARY and n not in hidden and not (n in TIMING and timing)]


def summary(results: list[dict]) -> dict:
    def share(rs: list[dict], key: str) -> float:
        return round(sum(bool(r[key]) for r in rs) / len(rs), 3) if rs else float("nan")

    out = {}
    for c in COMPANIONS + ("all",):
        rs = [r for r in results if c in ("all", r["companion"])]
        shown = [r for r in rs if not r["not_shown"]]
        if rs:
            keys = ("halved", "within_3x", "within_3x_or_exact", "silent", "wrong_library")
            out[c] = {k: share(rs, k) for k in keys} | {
                "companion_found_where_shown": share(shown, "companion_found"),
                "n": len(rs),
                "n_shown": len(shown),
            }
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", choices=("torsional", "coupled"), default="torsional")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument(
        "--outside",
        choices=("motor", "sensors"),
        default="motor",
        help="the outside kinds: the motor side's (default) or the encoders' readings",
    )
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=500.0)
    ap.add_argument("--out", type=Path, default=None, help="JSON lines, one per recording, appended as they finish")
    a = ap.parse_args()
    matrix = rows(a.seeds, a.first_seed, a.config, SENSORS if a.outside == "sensors" else None)[: a.limit]
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for row in matrix:
            r = run_row(row, a.duration, a.rate, Path(tmp))
            results.append(r)
            line = json.dumps(r, default=float)
            print(line, flush=True)
            if a.out is not None:
                with a.out.open("a") as fh:
                    fh.write(line + "\n")
    print(json.dumps(summary(results), indent=1))


if __name__ == "__main__":
    main()
