"""The README comparison table: every controller, torsional and coupled, from rest, targets 0.5-8 rad/s.

Writes docs/controller_table.md (+ the results CSV and the SSI figure in out/controller_table/) and prints the
table and the wall time.  Run: .venv/bin/python benchmarks/evaluate_table.py [--workers 2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from controllers.evaluation import DEFAULT_TARGETS, evaluate
from controllers.evaluation.report import markdown_table, write_report

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--controllers", default="baseline,pi,softtorque,observer,lqg")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--scenarios", default="rest,cycle,friction-20,friction+20,noisy")
    a = ap.parse_args()
    t0 = time.perf_counter()
    scenarios = a.scenarios.split(",")
    rows = evaluate(
        a.controllers.split(","),
        ["torsional", "coupled"],
        scenarios,
        DEFAULT_TARGETS,
        duration=a.duration,
        window=20.0,
        workers=a.workers,
    )
    wall = time.perf_counter() - t0
    write_report(rows, ROOT / "out" / "controller_table")
    table = markdown_table(rows, "rest")
    others = "".join(f"\n## scenario: {sc}\n\n" + markdown_table(rows, sc) for sc in scenarios if sc != "rest")
    text = (
        "# Controllers compared (from rest, SSI < 0.1 = no stick-slip)\n\n"
        "Produced by `benchmarks/evaluate_table.py` (harness `controllers.evaluation`, "
        f"{a.duration:g} s runs, last 20 s steady state, targets 0.5-8 rad/s in 0.5 rad/s steps). "
        "'lowest free target': lowest target from which every higher one is held: no stick-slip and the mean "
        "lower-disc speed within 10 % of the target; "
        "'stuck': the lower disc does not turn. Scenario 'rest' below; the other scenarios "
        "(start on a stick-slip cycle, brake friction -20 %/+20 %, 2048-count encoders with 1 mrad noise) "
        "follow.\n\n" + table + others
    )
    (ROOT / "docs" / "controller_table.md").write_text(text)
    print(table + others)
    print(f"{len(rows)} runs in {wall:.1f} s wall ({a.workers} workers)")


if __name__ == "__main__":
    main()
