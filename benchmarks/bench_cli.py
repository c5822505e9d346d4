"""How fast the command line answers: help, a refusal, ``import drillgym``.

    .venv/bin/python benchmarks/bench_cli.py [--runs 10] [--tree DIR]

Each case runs ``--runs`` times as a fresh process, as a user starts it; per case it prints the median
and the slowest wall time (s), the median CPU time (user + system, s: what the run costs whatever else
the machine does) and the peak resident memory (MB, the largest ``ru_maxrss`` of the runs). The peer
``python -c pass`` (the interpreter's own start, measured in the same run) is the floor; the goal on an
idle 2-core machine is 0.5 s median and 100 MB peak for the command line's cases and for ``import
drillgym``. The load average before and after is printed: figures taken beside other jobs are slower.

``--tree DIR`` measures the drillgym of another checkout with this venv (``PYTHONPATH=DIR``), e.g. the
commit before the imports on demand: ``mkdir /tmp/before && git archive 8c4d60e | tar -x -C /tmp/before``, then
``--tree /tmp/before``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
DRILLGYM = str(Path(PYTHON).with_name("drillgym"))

#: (label, argv, expected exit code)
CASES = (
    ("python -c pass (floor)", [PYTHON, "-c", "pass"], 0),
    ('python -c "import drillgym"', [PYTHON, "-c", "import drillgym"], 0),
    ("drillgym --help", [DRILLGYM, "--help"], 0),
    ("drillgym simulate --help", [DRILLGYM, "simulate", "--help"], 0),
    ("drillgym rig run --help", [DRILLGYM, "rig", "run", "--help"], 0),
    ("drillgym simulate --no-such-option", [DRILLGYM, "simulate", "--no-such-option"], 2),
)

#: runs argv once and prints its wall time and ru_maxrss (its only child is the measured process)
_ONE = """
import resource, subprocess, sys, time
t = time.perf_counter()
code = subprocess.call(sys.argv[2:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
dt = time.perf_counter() - t
r = resource.getrusage(resource.RUSAGE_CHILDREN)
print(code, dt, r.ru_maxrss, r.ru_utime + r.ru_stime)
"""


def run_once(argv: list[str], env: dict[str, str] | None = None, cwd: Path = ROOT) -> tuple[int, float, float, float]:
    """(exit code, wall time s, peak RSS MB, CPU time s) of one run of ``argv`` in a fresh measuring process.

    The measuring process holds no other child, so ``RUSAGE_CHILDREN`` is the measured process's own peak.
    """
    out = subprocess.run(
        [PYTHON, "-c", _ONE, "--", *argv], capture_output=True, text=True, check=True, cwd=cwd, env=env
    ).stdout.split()
    return int(out[0]), float(out[1]), int(out[2]) / 1024, float(out[3])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="runs of each case (default 10)")
    ap.add_argument("--tree", type=Path, help="measure the drillgym of this checkout instead of the installed one")
    args = ap.parse_args()
    env, cwd = None, ROOT  # the working directory is first on the path of ``python -c``
    if args.tree is not None:
        cwd = args.tree.resolve()
        env = {**os.environ, "PYTHONPATH": str(args.tree.resolve())}
        print(f"drillgym of {args.tree.resolve()}")
    if not Path(DRILLGYM).exists():
        sys.exit(f"bench_cli: {DRILLGYM} not found: run it with the venv's python (.venv/bin/python)")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {args.runs} runs per case")
    print(f"{'case':<40} {'median s':>9} {'max s':>7} {'cpu s':>7} {'peak MB':>8}")
    for label, argv, expected in CASES:
        run_once(argv, env, cwd)  # warm the file cache (and the byte-compiled modules) first
        times, peaks, cpus = [], [], []
        for _ in range(args.runs):
            code, dt, peak, cpu = run_once(argv, env, cwd)
            if code != expected:
                sys.exit(f"bench_cli: {label} exited {code}, expected {expected}")
            times.append(dt)
            peaks.append(peak)
            cpus.append(cpu)
        print(
            f"{label:<40} {statistics.median(times):9.3f} {max(times):7.3f} {statistics.median(cpus):7.3f} "
            f"{max(peaks):8.1f}"
        )
        time.sleep(0.2)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
