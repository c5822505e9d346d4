"""The diagnosis JSON of a fixed matrix of independent-rig recordings, one file per recording.

Writes what ``drillgym diagnose DATA --json`` prints for each recording of a fixed matrix, so that two
checkouts can be compared byte for byte (``diff -r``): a change meant to keep the diagnosis' behaviour
must leave every file as it was.

The recordings come from the independent rig of :mod:`bench_diagnosis_rig` (docs/model.md written again
for scipy's ``solve_ivp``, not drillgym's simulator): the quick matrix of
:func:`bench_diagnosis_selection.build_matrix` (clean recordings, base parameters off, two or three
library effects at once, effects outside the library), two random combinations of a second matrix
(:data:`SECOND_SEED`), and a few recordings chosen for the paths the quick matrix may miss
(:data:`EXTRA`): a motor lag under base mismatch at 500 Hz (the check at the recording's own rate with
the base parameters refitted), a brake asymmetry beside a friction drift (the split-half check of a
position-dependent effect), a lag on ramps at 200 Hz (a smooth input), and one diagnosis with the base
parameters held (``--fixed-base``).  Each recording is written once to the recordings directory (CSV, as
docs/data_format.md; an existing file is kept, so every checkout reads the same bytes)
and diagnosed through the command line in the process of a worker, in a working directory of the run's own
(``OUT_work``) on a link to the recording; the candidate effect file that ``diagnose`` writes next to the
recording is copied beside its JSON.

    PYTHONPATH=CHECKOUT .venv/bin/python benchmarks/diagnosis_json_snapshot.py --recordings DIR --out DIR
        [--jobs 2] [--only NAME,NAME]
    diff -r OUT_A OUT_B

The output directory holds ``NAME.json`` (the command's standard output), ``NAME_candidate.py`` when a
candidate was written, and ``NAME.error.txt`` when the command failed; wall times are printed only, never
written there.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: the second matrix's seed (random combinations of library effects, :func:`bench_diagnosis_selection.random_combos`)
#: and the cases taken from it: a motor lag beside a brake asymmetry on ramps at 1 kHz with the base parameters off
#: (the check at the recording's rate on a smooth input), and three effects on the coupled rig with an LVDT offset
SECOND_SEED, SECOND_CASES = 101, (2, 3)
#: recordings beyond those: (configuration, signal, duration s, rate Hz, noise and input seed, hidden effects,
#: base parameter factors, input offset V, input amplitude V, extra command options)
EXTRA = [
    (
        "torsional",
        "steps",
        30.0,
        500.0,
        4031,
        {"motor_lag": {"tau_m": 0.035}},
        {"km": 0.96, "Ts": 1.05, "Jl": 1.04},
        1.2,
        3.0,
        (),
    ),
    (
        "torsional",
        "sum_of_sines",
        30.0,
        1000.0,
        6589,
        {"brake_asymmetry": {"asym_s": 0.367, "asym_c": 0.214}, "friction_drift": {"drift": -0.0041}},
        {},
        0.0,
        3.0,
        (),
    ),
    ("torsional", "ramps", 20.0, 200.0, 808, {"motor_lag": {"tau_m": 0.029}}, {}, 1.3, 3.0, ()),
    (
        "torsional",
        "quasi_random",
        20.0,
        500.0,
        77,
        {},
        {"km": 0.97, "Ts": 1.06, "Jl": 1.04},
        1.0,
        3.0,
        ("--fixed-base",),
    ),
]


def _name(i: int, c: dict) -> str:
    """A recording's file name from its content: index, kind, configuration, effects, base off, input."""
    eff = "+".join(c["effects"]) or "none"
    base = "_base-off" if c["scale"] else ""
    opts = "".join(o.replace("--", "_") for o in c.get("options", ()))
    return (
        f"{i:02d}_{c['kind']}_{c['config']}_{eff}{base}_{c['signal']}_{c['duration']:.0f}s_{c['rate_hz']:.0f}Hz{opts}"
    )


def cases() -> list[dict]:
    """The matrix: the quick selection matrix, then :data:`EXTRA`; each case with its file ``name``."""
    from bench_diagnosis_selection import build_matrix

    out = [dict(c, options=()) for c in build_matrix(quick=True)]
    second = build_matrix(seed=SECOND_SEED, random_n=max(SECOND_CASES) + 1)
    out += [dict(second[i], options=()) for i in SECOND_CASES]
    for config, signal, dur, rate, seed, effects, scale, offset, amp, opts in EXTRA:
        out.append(
            {
                "kind": "extra",
                "config": config,
                "signal": signal,
                "duration": dur,
                "rate_hz": rate,
                "seed": seed,
                "effects": effects,
                "scale": scale,
                "offset": offset,
                "amplitude": amp,
                "options": opts,
            }
        )
    for i, c in enumerate(out):
        c["name"] = _name(i, c)
    return out


def write_recording(c: dict, directory: Path) -> Path:
    """The case's recording as a CSV file in ``directory`` (made once: an existing file is kept)."""
    path = directory / f"{c['name']}.csv"
    if path.exists():
        return path
    from bench_diagnosis_rig import rig_recording

    from drillgym.io import write_timeseries

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
    tmp = path.with_suffix(f".{os.getpid()}.tmp.csv")
    write_timeseries(tmp, ts)
    tmp.replace(path)
    return path


def diagnose_case(c: dict, recordings: Path, out: Path) -> tuple[str, float, int]:
    """``drillgym diagnose RECORDING --json`` for one case; (name, wall time s, exit code).

    The command runs in a working directory of this run's own (``OUT_work``, beside ``out``), on a link to
    the recording given by its relative name: the candidate file lands there, and its path in the JSON
    (``NAME_candidate.py:NAME``) is the same for every run, so that two runs can go side by side."""
    from typer.testing import CliRunner

    from drillgym.cli import app

    work = out.parent / f"{out.name}_work"
    work.mkdir(exist_ok=True)
    link = work / f"{c['name']}.csv"
    if not link.exists():
        link.symlink_to((recordings / f"{c['name']}.csv").resolve())
    os.chdir(work)
    cand = Path(f"{c['name']}_candidate.py")
    cand.unlink(missing_ok=True)
    t0 = time.perf_counter()
    res = CliRunner().invoke(app, ["diagnose", link.name, "--json", *c["options"]])
    wall = time.perf_counter() - t0
    if res.exit_code == 0:
        (out / f"{c['name']}.json").write_text(res.stdout, encoding="utf-8")
    else:
        import traceback

        trace = "".join(traceback.format_exception(res.exception)) if res.exception else ""
        (out / f"{c['name']}.error.txt").write_text(f"exit {res.exit_code}\n{res.output}\n{trace}", encoding="utf-8")
    if cand.exists():
        shutil.copyfile(cand, out / cand.name)
    return c["name"], wall, res.exit_code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--recordings", type=Path, required=True, help="directory of the recordings (made if missing)")
    ap.add_argument("--out", type=Path, required=True, help="directory for the JSON files (must be new or empty)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default=None, help="comma-separated case names (or name prefixes) to run")
    a = ap.parse_args()
    import drillgym

    todo = cases()
    if a.only:
        keys = a.only.split(",")
        todo = [c for c in todo if any(c["name"].startswith(k) for k in keys)]
    a.recordings = a.recordings.resolve()
    a.out = a.out.resolve()
    a.recordings.mkdir(parents=True, exist_ok=True)
    a.out.mkdir(parents=True, exist_ok=True)
    if any(a.out.iterdir()):
        raise SystemExit(f"{a.out} is not empty")
    print(f"{len(todo)} recordings, drillgym from {Path(drillgym.__file__).parent}, {a.jobs} processes", flush=True)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        list(pool.map(write_recording, todo, [a.recordings] * len(todo)))  # every file before any diagnosis
        order = sorted(todo, key=lambda c: -c["duration"] * c["rate_hz"])
        futures = [pool.submit(diagnose_case, c, a.recordings, a.out) for c in order]
        for f in futures:
            name, wall, code = f.result()
            print(f"{wall:7.1f} s  exit {code}  {name}", flush=True)
    print(f"wall time {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
