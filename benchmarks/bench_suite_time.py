"""How long the test suite takes on a fresh clone, from an empty kernel cache, and warm.

    .venv/bin/python benchmarks/bench_suite_time.py [--tests PATH ...] [--skip-prepare] [--skip-warm]
    .venv/bin/python benchmarks/bench_suite_time.py --fresh-clone

A fresh clone has no compiled kernels: numba compiles drillgym's own kernels (``cache=True``: next to the
sources, or in ``$NUMBA_CACHE_DIR``) and the generated kernels of every composition (``$DRILLGYM_KERNEL_CACHE``,
:mod:`drillgym.effects.codegen`) on first use. This script copies nothing: it points both caches at one empty
temporary directory (removed at the end; the caches the checkout already has are not read), then times, each
phase a fresh process from the repository's root:

1. prepare: ``drillgym prepare``, as ``make venv`` runs it (compiles the models ``diagnose`` runs);
2. cold: the suite as ``make test`` runs it, ``python -m pytest -q -n 2 --dist loadgroup tests`` (the lint
   before it takes seconds and compiles nothing, so it is not timed), with ``--durations=15``;
3. warm: the same command again on the now-filled cache: the peer, measured in the same run.

It prints each phase's wall time, its CPU time (user + system of the processes that ended), pytest's summary
line, the total from an empty cache (prepare + cold), the slowest 15 tests of each suite run and the line
``cold N s, warm M s (ratio R)``; the load average before and after (other jobs slow the wall time, not the
CPU time). ``--tests PATH ...`` times these test files or directories instead of ``tests``; ``--skip-prepare``
leaves out phase 1 (the suite then compiles what prepare would have); ``--skip-warm`` leaves out phase 3. The
exit code is 1 when a phase failed (its output's failures are printed), else 0.

``--fresh-clone`` times the two README commands as a newcomer runs them instead: the repository's committed
``HEAD`` cloned into a temporary directory, ``XDG_CACHE_HOME`` pointed at an empty one (pip's downloads,
drillgym's kernels and matplotlib's fonts start empty; ``NUMBA_CACHE_DIR`` and ``DRILLGYM_KERNEL_CACHE``
unset), then ``make demo`` (the virtual environment, ``drillgym prepare``, the demo) and ``make test`` (the lint
and the suite), each timed; the goal is both within 20 minutes together. Both temporary directories are removed
at the end.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
DRILLGYM = str(Path(PYTHON).with_name("drillgym"))
#: the suite as ``make test`` runs it (Makefile), plus the slowest tests
SUITE = [PYTHON, "-m", "pytest", "-q", "-n", "2", "--dist", "loadgroup", "--durations=15"]

_DURATION = re.compile(r"^\s*\d+(\.\d+)?s\s+(call|setup|teardown)\s+\S")
_SUMMARY = re.compile(r"\d+ (passed|failed|errors?|skipped)\b.* in \d")


@dataclass
class Phase:
    name: str
    wall: float
    cpu: float
    code: int
    output: str = field(repr=False)

    def summary(self) -> str:
        """pytest's last summary line ('127 passed in 140.32s'), or the exit code's meaning."""
        lines = [s.strip(" =") for s in self.output.splitlines() if _SUMMARY.search(s)]
        return lines[-1] if lines else ("done" if self.code == 0 else f"exit code {self.code}")

    def slowest(self) -> list[str]:
        """The lines of pytest's 'slowest durations' section."""
        return [s.rstrip() for s in self.output.splitlines() if _DURATION.match(s)]

    def failures(self) -> list[str]:
        lines = [s for s in self.output.splitlines() if s.startswith(("FAILED", "ERROR"))]
        return lines or self.output.splitlines()[-30:]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_phase(name: str, argv: list[str], env: dict[str, str]) -> Phase:
    """Run ``argv`` from the repository's root with ``env``; its wall and CPU time, exit code and output."""
    print(f"{name}: {' '.join(Path(a).name if a in (PYTHON, DRILLGYM) else a for a in argv)}", flush=True)
    cpu0, t0 = _cpu(), time.perf_counter()
    res = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    phase = Phase(name, time.perf_counter() - t0, _cpu() - cpu0, res.returncode, res.stdout)
    print(f"{name}: {phase.wall:.0f} s wall, {phase.cpu:.0f} s CPU, {phase.summary()}", flush=True)
    return phase


def exit_code(phases: list[Phase]) -> int:
    """Print the failures of the phases that failed; 1 when one did, else 0."""
    failed = [p for p in phases if p.code != 0]
    for p in failed:
        print(f"\n{p.name} failed (exit code {p.code}):")
        print("\n".join(p.failures()))
    return 1 if failed else 0


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def fresh_clone() -> int:
    """``make demo`` then ``make test`` in a clone of HEAD with empty caches (see the module docstring)."""
    phases: list[Phase] = []
    with (
        tempfile.TemporaryDirectory(prefix="drillgym-clone-") as clone,
        tempfile.TemporaryDirectory(prefix="drillgym-empty-xdg-") as xdg,
    ):
        subprocess.run(["git", "clone", "-q", str(ROOT), clone], check=True)
        env = {
            k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "DRILLGYM_KERNEL_CACHE", "VIRTUAL_ENV")
        }
        env["XDG_CACHE_HOME"] = xdg
        head = subprocess.run(["git", "-C", clone, "log", "--oneline", "-1"], capture_output=True, text=True).stdout
        print(f"fresh clone of {head.strip()} in {clone}; empty XDG_CACHE_HOME {xdg}")
        print(f"load average before: {_load()}", flush=True)
        for target in ("demo", "test"):
            phases.append(run_phase(f"make {target}", ["make", "-C", clone, target], env))
            if phases[-1].code != 0:
                break
        print(f"load average after: {_load()}")
    print()
    for p in phases:
        print(f"{p.name:<12} {p.wall:8.1f} s wall {p.cpu:8.1f} s CPU  {p.summary()}")
    total = sum(p.wall for p in phases)
    print(f"make demo + make test from a fresh clone: {total:.0f} s ({total / 60:.1f} min; goal 20 min)")
    return exit_code(phases)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tests", nargs="+", default=["tests"], metavar="PATH", help="test paths (default: tests)")
    ap.add_argument("--skip-prepare", action="store_true", help="do not run `drillgym prepare` first")
    ap.add_argument("--skip-warm", action="store_true", help="do not run the suite a second time on the filled cache")
    ap.add_argument(
        "--fresh-clone", action="store_true", help="time `make demo` then `make test` in a clone with empty caches"
    )
    args = ap.parse_args()
    if args.fresh_clone:
        return fresh_clone()
    if not Path(DRILLGYM).exists():
        sys.exit(f"bench_suite_time: {DRILLGYM} not found: run it with the venv's python (.venv/bin/python)")
    missing = [p for p in args.tests if not (ROOT / p.split("::")[0]).exists()]
    if missing:
        sys.exit(f"bench_suite_time: no such test path (relative to {ROOT}): {' '.join(missing)}")
    phases: list[Phase] = []
    with tempfile.TemporaryDirectory(prefix="drillgym-empty-cache-") as tmp:
        env = {
            **os.environ,
            "NUMBA_CACHE_DIR": str(Path(tmp) / "numba"),
            "DRILLGYM_KERNEL_CACHE": str(Path(tmp) / "kernels"),
        }
        print(f"empty kernel caches in {tmp} (NUMBA_CACHE_DIR, DRILLGYM_KERNEL_CACHE); tests: {' '.join(args.tests)}")
        print(f"load average before: {_load()}", flush=True)
        if not args.skip_prepare:
            phases.append(run_phase("prepare", [DRILLGYM, "prepare"], env))
        cold = run_phase("cold suite", SUITE + args.tests, env)
        phases.append(cold)
        warm = None if args.skip_warm else run_phase("warm suite", SUITE + args.tests, env)
        if warm is not None:
            phases.append(warm)
        print(f"load average after: {_load()}")
    print()
    print(f"{'phase':<12} {'wall s':>8} {'CPU s':>8}  result")
    for p in phases:
        print(f"{p.name:<12} {p.wall:8.1f} {p.cpu:8.1f}  {p.summary()}")
    fresh = [p for p in phases if p.name in ("prepare", "cold suite")]
    print(f"total from an empty cache ({' + '.join(p.name for p in fresh)}): {sum(p.wall for p in fresh):.0f} s")
    for p in (cold, warm):
        if p is not None:
            print(f"\nslowest 15 of the {p.name}:")
            print("\n".join(p.slowest()) or "(none reported)")
    if warm is not None:
        print(f"\ncold {cold.wall:.0f} s, warm {warm.wall:.0f} s (ratio {cold.wall / warm.wall:.2f})")
    return exit_code(phases)


if __name__ == "__main__":
    sys.exit(main())
