"""The target-switched learned policy over seeds, against the best classical motor-angle controller.

For each seed s, the two networks that ``drillgym train --seeds`` wrote (``LOW/seed_s``: trained on the
nominal rig, ``ppo_distill.yml``; ``HIGH/seed_s``: trained on the plant population with the speed command
from above, ``ppo_distill_command.yml``) are combined at ``--edge`` rad/s (``drillgym combine-policies``)
and evaluated in the same run as ``descent`` (the best classical controller on the motor
angle): the lowest held target from rest on the nominal rig, and each plant's lowest held target on the
robust-control plant population (``drillgym evaluate --scenarios plants``, 20 plants, population seeds 0
and 1): median, 90th percentile, worst, plants holding none.  Over the seeds: median, interquartile mean
and its bootstrap 95 % interval (``agents.seeds``); a seed holding nothing counts as 8.5 rad/s.

    .venv/bin/python benchmarks/bench_learned_switched.py --low runs/learned --high runs/learned_robust \\
        --seeds 1,2,3,4,5 [--edge 3.0] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DRILLGYM = [sys.executable, "-m", "drillgym.cli"]
NOT_HELD = 8.5


def _value(cell: str) -> float:
    return NOT_HELD if cell.strip() in ("none", "nan", "") else float(cell)


def evaluate(controller: str, population: int, out: Path) -> dict[str, float]:
    """Nominal lowest held target and the population's median / p90 / worst / none of ``controller``."""
    subprocess.run(
        [
            *DRILLGYM,
            "evaluate",
            "--config",
            "torsional",
            "--controllers",
            controller,
            "--scenarios",
            "rest,plants",
            "--plants",
            "20",
            "--seed",
            str(population),
            "--out",
            str(out),
            "--workers",
            "2",
        ],
        check=True,
        capture_output=True,
        cwd=ROOT,
    )
    rows = [
        [c.strip() for c in line.split("|")]
        for line in (out / "summary.md").read_text().splitlines()
        if line.startswith(f"| {controller} |")
    ]
    rest, plants = rows[0], rows[1]
    return {
        "nominal": _value(rest[3]),
        "median": _value(plants[5]),
        "p90": _value(plants[6]),
        "worst": _value(plants[7]),
        "none": float(plants[8]),
    }


def main() -> None:
    from agents.seeds import iqm, iqm_ci

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--low", type=Path, required=True, help="run directory of the nominal-trained seeds (seed_<s>/)")
    ap.add_argument("--high", type=Path, required=True, help="run directory of the population-trained seeds")
    ap.add_argument("--seeds", default="1,2,3,4,5")
    ap.add_argument("--edge", type=float, default=3.0, help="target (rad/s) from which the population network serves")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    work = Path(tempfile.mkdtemp(prefix="bench_switched_"))
    table: dict[str, dict] = {}
    print(
        f"target-switched policy: nominal-trained network below {args.edge:g} rad/s, population-trained from it; "
        f"harness: 60 s from rest, last 20 s; populations of 20 plants, seeds 0 and 1"
    )
    print(
        f"{'policy':<12} {'nominal':>8} | {'pop 0: median  p90  worst none':>31} | "
        f"{'pop 1: median  p90  worst none':>31}"
    )
    runs = {f"seed {s}": f"agent:{work / f'seed_{s}.npz'}" for s in seeds} | {"descent": "descent"}
    for s in seeds:
        subprocess.run(
            [
                *DRILLGYM,
                "combine-policies",
                str(args.low / f"seed_{s}"),
                str(args.high / f"seed_{s}"),
                "--edges",
                f"{args.edge:g}",
                "--out",
                str(work / f"seed_{s}.npz"),
            ],
            check=True,
            capture_output=True,
            cwd=ROOT,
        )
    for name, ctrl in runs.items():
        r0, r1 = (evaluate(ctrl, p, work / f"{name.replace(' ', '_')}_pop{p}") for p in (0, 1))
        table[name] = {"nominal": r0["nominal"], "pop0": r0, "pop1": r1}
        cells = lambda r: f"{r['median']:>13.2f} {r['p90']:>4.2f} {r['worst']:>6.2f} {r['none']:>4.0f}"  # noqa: E731
        print(f"{name:<12} {r0['nominal']:>8.2f} | {cells(r0):>31} | {cells(r1):>31}", flush=True)
    print(f"over {len(seeds)} seeds (a seed holding nothing counts as {NOT_HELD} rad/s):")
    for label, key in [
        ("nominal lowest held", lambda r: r["nominal"]),
        ("pop 0 p90", lambda r: r["pop0"]["p90"]),
        ("pop 1 p90", lambda r: r["pop1"]["p90"]),
    ]:
        v = np.array([key(table[f"seed {s}"]) for s in seeds])
        lo, hi = iqm_ci(v)
        print(
            f"  {label:<20} median {np.median(v):.2f}, IQM {iqm(v):.2f} [{lo:.2f}, {hi:.2f}]; per seed "
            + ", ".join(f"{x:.2f}" for x in v)
            + f"; descent {key(table['descent']):.2f}"
        )
    if args.json:
        args.json.write_text(json.dumps(table, indent=1))


if __name__ == "__main__":
    main()
