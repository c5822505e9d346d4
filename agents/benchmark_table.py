"""The reference table of the named tasks: every classical controller and every kept learned policy that fits
a task's sensing and configuration, scored by :func:`agents.benchmark.run_benchmark`, one markdown row each
with its exact command and the CPU time it took.

    .venv/bin/python -m agents.benchmark_table --out out/benchmark_table.md [--plants 10 --duration 40 ...]
    .venv/bin/python -m agents.benchmark_table --out out/identified.md --tasks drillgym/Population-Motor-Identified-v0 \
        --identified out/identified_plants     # an identified task: its plants identified once, for every row
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from drillgym.envs.tasks import SENSORS, TASKS, BenchmarkTask
from drillgym.errors import DrillgymError

from .benchmark import BenchmarkOptions, BenchmarkResult, check_sensing, run_benchmark

__all__ = ["candidate_policies", "table_header", "table_row", "main"]

POLICY_DIR = Path(__file__).resolve().parent / "policies"


def candidate_policies() -> list[str]:
    """Every registered classical controller (``baseline`` included, the open-loop reference) and every kept
    learned policy (``agent:agents/policies/<name>/policy.npz``, relative to the working directory when it
    lies below it)."""
    from controllers import available

    out = list(available())
    for p in sorted(POLICY_DIR.glob("*/policy.npz")):
        try:
            p = p.relative_to(Path.cwd())
        except ValueError:
            pass
        out.append(f"agent:{p}")
    return out


def fits(task: BenchmarkTask, spec: str) -> bool:
    """True when the policy runs in the task's configuration, reads only its sensors and, on a task with more
    than the motor encoder, reads more than the motor encoder (a motor-side policy scores there exactly as
    on the motor task of the same rig: the same plants, targets and noise seed, the same runs)."""
    from controllers import make

    try:
        check_sensing(task, spec)
    except DrillgymError:
        return False
    if task.sensors == "motor":
        return True
    uses = make(spec, config=task.config, omega_ref=task.protocol.targets[-1]).uses
    return any(m not in SENSORS["motor"][1] for m in uses)


def _fmt(v: float) -> str:
    return "none" if math.isinf(v) else f"{v:.2f}"


#: the columns of a task's table; a coupled task's adds the whirl and the plants it limited after the SSI
COLUMNS = ("policy", "median (rad/s)", "90th pct (rad/s)", "SSI", "energy (J/run)", "plants holding none", "CPU (s)")
WHIRL_COLUMNS = ("whirl", "plants limited by whirl")


def table_header(task: BenchmarkTask) -> str:
    """The markdown header of a task's table (two lines)."""
    cols = list(COLUMNS)
    if task.config == "coupled":
        cols[4:4] = WHIRL_COLUMNS
    cols.append("command")
    return "| " + " | ".join(cols) + " |\n" + "|---" * len(cols) + "|\n"


def table_row(res: BenchmarkResult, command: str, cpu_s: float) -> str:
    """One markdown row: policy, median / 90th pct (rad/s), SSI, on a coupled task the whirl and the plants it
    limited, energy (J/run), plants holding none, CPU s, command."""
    s = res.scores[0]
    whirl = f"{s.whirl:.3g} | {s.whirl_limited} | " if TASKS[res.task].config == "coupled" else ""
    return (
        f"| `{s.policy}` | {_fmt(s.median)} | {_fmt(s.p90)} | {s.ssi:.3g} | {whirl}{s.energy:.0f} | {s.none_held} | "
        f"{cpu_s:.0f} | `{command}` |"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Measure the table (see the module doc); writes markdown to ``--out`` and the results as JSON lines."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="markdown file of the table")
    ap.add_argument("--tasks", default="", help="task ids, comma-separated (default all)")
    ap.add_argument("--policies", default="", help="specs, comma-separated (default candidate_policies())")
    ap.add_argument("--plants", type=int, default=None)
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--window", type=float, default=None)
    ap.add_argument("--targets", default="", help="comma-separated (rad/s)")
    ap.add_argument("--identified", type=Path, default=None, help="identified tasks: the plants' models folder")
    a = ap.parse_args(argv)
    tasks = [TASKS[t] for t in a.tasks.split(",") if t] if a.tasks else list(TASKS.values())
    specs = [s for s in a.policies.split(",") if s] if a.policies else candidate_policies()
    tg = tuple(float(v) for v in a.targets.split(",")) if a.targets else None
    opts = BenchmarkOptions(a.plants, a.duration, a.window, tg)
    flags = "".join(
        f" --{k} {v}"
        for k, v in (("plants", a.plants), ("duration", a.duration), ("window", a.window), ("targets", a.targets))
        if v not in (None, "")
    )
    a.out.parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "a", encoding="utf-8") as md, open(a.out.with_suffix(".jsonl"), "a", encoding="utf-8") as js:
        for task in tasks:
            md.write(f"\n### {task.id}\n\n" + table_header(task))
            for spec in specs:
                if not fits(task, spec):
                    continue
                t0 = time.process_time()
                ident = a.identified if task.identified else None
                res = run_benchmark(task.id, [spec], replace(opts, identified_dir=ident))
                cpu = time.process_time() - t0
                cmd = f"drillgym benchmark {task.id} --policy {spec}{flags}"
                cmd += f" --identified {ident}" if ident else ""
                md.write(table_row(res, cmd, cpu) + "\n")
                md.flush()
                from drillgym.io.jsonfile import dumps_json

                js.write(dumps_json({**res.to_json(), "cpu_s": cpu, "command": cmd}) + "\n")
                js.flush()
                print(json.dumps({"task": task.id, "policy": spec, "cpu_s": round(cpu, 1)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
