"""Reply times of long runs on the emulated rig: does a run at 2 ms ever stop without a fault?

    .venv/bin/python benchmarks/bench_rig_reply_times.py [--runs 10] [--duration 600] [--control-ms 2]
        [--controller observer] [--parallel 1]

Each run starts its own emulator (``drillgym rig emulate --port LINK``, a separate process, as an
operator runs it) and one episode of ``drillgym rig run --controller C --control-ms P --duration D``
against it, both as the command line runs them (real-time scheduling where permitted).  Per run it
prints: completed or stopped (with the stop's reason), the number of commands, the host's reply times
(command sent -> its SAMPLE received) at p50/p90/p99/p99.9 and their maximum (ms), and the emulator's
worst service time (command read -> SAMPLE written) with its longest garbage-collector pause; then the
totals.  A stop is a failure: the firmware's watchdog and the host's reply timeout are 100 ms, nothing
else in the run can stop it (the emulated plant runs no effect, the controller stays within the limits).

``--runs 1 --duration 3`` is a smoke test (tests/test_hw_reply_times.py runs it).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
QUANTILES = ("p50", "p90", "p99", "p99.9", "max")
_REPLY = re.compile(
    r"reply time .* over (\d+) commands: p50 ([\d.]+), p90 ([\d.]+), p99 ([\d.]+), p99\.9 ([\d.]+), max ([\d.]+) ms"
)
_SERVICE = re.compile(r"service time p50 [\d.]+, p90 [\d.]+, p99 [\d.]+, p99\.9 [\d.]+, max ([\d.]+) ms")
_GC = re.compile(r"longest ([\d.]+) ms \(generation")
_STEPS = re.compile(r"^(\d+) steps", re.M)
_SERVED = re.compile(r"(\d+) commands served")
READY_TIMEOUT_S = 180.0  # the emulator's start (imports, compiled kernels) on a loaded machine
STEAL_SAMPLE_S = 0.05  # the steal-time monitor's sampling period


class StealMonitor:
    """The hypervisor's steal time (``/proc/stat``) while a run goes: its longest burst.

    A virtual machine whose CPUs are taken away as a whole pauses the emulator and the host at once; a
    watchdog stop then is the host's silence as the firmware would see it, but no program on the
    machine caused it.  Sampled every :data:`STEAL_SAMPLE_S` seconds in a thread.
    """

    def __init__(self) -> None:
        self.longest_ms = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._tick_ms = 1e3 / os.sysconf("SC_CLK_TCK")

    @staticmethod
    def _steal_ticks() -> int:
        with open("/proc/stat") as fh:
            fields = fh.readline().split()
        return int(fields[8]) if len(fields) > 8 else 0

    def _run(self) -> None:
        last = self._steal_ticks()
        while not self._stop.wait(STEAL_SAMPLE_S):
            now = self._steal_ticks()
            self.longest_ms = max(self.longest_ms, (now - last) * self._tick_ms)
            last = now

    def __enter__(self) -> StealMonitor:
        if os.path.exists("/proc/stat"):
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()


@dataclass
class RunResult:
    """One run: how it ended, its commands and reply times (ms), the emulator's worst service time (ms)."""

    completed: bool
    stop: str | None
    commands: int
    reply_ms: dict[str, float] = field(default_factory=dict)
    service_max_ms: float = math.nan
    gc_longest_ms: float = math.nan
    wall_s: float = 0.0
    steal_longest_ms: float = math.nan
    kept: str | None = None

    def line(self) -> str:
        """The run's one-line report."""
        how = "completed" if self.completed else f"STOPPED ({self.stop})"
        reply = ", ".join(f"{q} {self.reply_ms[q]:.2f}" for q in QUANTILES) if self.reply_ms else "none"
        return (
            f"{how}; {self.commands} commands; reply time {reply} ms; emulator worst service time "
            f"{self.service_max_ms:.2f} ms, longest GC pause {self.gc_longest_ms:.2f} ms; longest steal burst "
            f"{self.steal_longest_ms:.0f} ms of CPU in {STEAL_SAMPLE_S * 1e3:.0f} ms; {self.wall_s:.0f} s wall"
            + (f"; logs kept in {self.kept}" if self.kept else "")
        )


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "drillgym.cli", *args]


def _plant_step(control_s: float) -> float:
    """The emulator's plant step: 1 ms, or the control period divided into whole steps of at most 1 ms."""
    return control_s / max(1, math.ceil(control_s / 1e-3 - 1e-9))


def _start_emulator(link: Path, control_s: float, log: Path) -> subprocess.Popen:
    with log.open("w") as fh:
        emu = subprocess.Popen(
            _cli("rig", "emulate", "--port", str(link), "--dt", repr(_plant_step(control_s))),
            stdout=subprocess.DEVNULL,
            stderr=fh,
            env=ENV,
            start_new_session=True,  # Ctrl-C of the benchmark reaches it through its SIGTERM only
        )
    deadline = time.monotonic() + READY_TIMEOUT_S
    while "emulator ready" not in log.read_text():
        if emu.poll() is not None or time.monotonic() > deadline:
            _stop(emu)
            raise RuntimeError(f"the emulator did not start: {log.read_text().strip()[-500:]}")
        time.sleep(0.2)
    return emu


def _stop(emu: subprocess.Popen) -> None:
    if emu.poll() is None:
        emu.send_signal(signal.SIGTERM)
        try:
            emu.wait(timeout=30)
        except subprocess.TimeoutExpired:
            emu.kill()
            emu.wait()


def run_once(
    workdir: Path, duration: float, control_ms: float = 2.0, controller: str = "observer", omega_ref: float = 1.0
) -> RunResult:
    """One emulator, one episode of ``duration`` s on it; the run's result.

    Parameters
    ----------
    workdir : path
        An empty directory for the link, the recording and the emulator's log.
    duration : float
        Episode length (s).
    control_ms : float, optional
        Control period (ms).
    controller : str, optional
        ``rig run --controller``.
    omega_ref : float, optional
        Target lower-disc speed (rad/s).
    """
    workdir = Path(workdir)
    link, log = workdir / "rig", workdir / "emulator.log"
    emu = _start_emulator(link, control_ms * 1e-3, log)
    t0 = time.monotonic()
    try:
        with StealMonitor() as steal:
            host = subprocess.run(
                _cli(
                    "rig", "run", "--port", str(link), "--controller", controller,
                    "--control-ms", f"{control_ms:g}", "--omega-ref", f"{omega_ref:g}",
                    "--duration", f"{duration:g}", "--record", str(workdir / "run.csv"),
                ),
                capture_output=True,
                text=True,
                env=ENV,
                timeout=1.5 * duration + 300,
            )  # fmt: skip
    finally:
        wall = time.monotonic() - t0
        _stop(emu)
    res = _result(host, log.read_text(), wall)
    res.steal_longest_ms = steal.longest_ms
    if not res.completed:  # a stop is kept for its diagnosis: the host's output and the emulator's log
        kept = Path(tempfile.mkdtemp(prefix="bench_rig_stop_"))
        (kept / "host.out").write_text(host.stdout)
        (kept / "host.err").write_text(host.stderr)
        (kept / "emulator.log").write_text(log.read_text())
        res.kept = str(kept)
    return res


def _result(host: subprocess.CompletedProcess, emulator_log: str, wall: float) -> RunResult:
    out, err = host.stdout, host.stderr
    m = _REPLY.search(out)
    steps = _STEPS.search(out)
    stop = None
    if host.returncode != 0:
        lines = [ln for ln in err.splitlines() if ln.startswith("drillgym:")] or err.strip().splitlines()[-1:]
        stop = f"exit {host.returncode}: {lines[-1] if lines else 'no message'}"
    served = _SERVED.search(emulator_log)  # a stopped run prints no summary: the emulator's count (rest phase included)
    res = RunResult(
        completed=host.returncode == 0,
        stop=stop,
        commands=int(m.group(1)) if m else int(steps.group(1)) if steps else int(served.group(1)) if served else 0,
        wall_s=wall,
    )
    if m:
        res.reply_ms = dict(zip(QUANTILES, map(float, m.groups()[1:])))
    s, g = _SERVICE.search(emulator_log), _GC.search(emulator_log)
    res.service_max_ms = float(s.group(1)) if s else math.nan
    res.gc_longest_ms = float(g.group(1)) if g else math.nan
    return res


def totals(results: list[RunResult]) -> str:
    """The summary line of all runs: completed and stopped, commands, the worst of each reply-time figure."""
    done = sum(r.completed for r in results)
    timed = [r for r in results if r.reply_ms]
    worst = ", ".join(f"{q} {max(r.reply_ms[q] for r in timed):.2f}" for q in QUANTILES) if timed else "none"
    service = max((r.service_max_ms for r in results if not math.isnan(r.service_max_ms)), default=math.nan)
    return (
        f"{len(results)} runs: {done} completed, {len(results) - done} stopped; "
        f"{sum(r.commands for r in results)} commands; worst reply time per figure over the runs: {worst} ms; "
        f"emulator worst service time {service:.2f} ms"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="number of runs (default 10)")
    ap.add_argument("--duration", type=float, default=600.0, help="episode length of each run (s, default 600)")
    ap.add_argument("--control-ms", type=float, default=2.0, help="control period (ms, default 2)")
    ap.add_argument("--controller", default="observer", help="rig run --controller (default observer)")
    ap.add_argument("--omega-ref", type=float, default=1.0, help="target lower-disc speed (rad/s, default 1)")
    ap.add_argument("--parallel", type=int, default=1, help="runs side by side (each its own emulator; default 1)")
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # stopped: each run's finally stops its emulator
    if args.runs < 1 or args.parallel < 1:
        ap.error(f"--runs and --parallel must be >= 1, got {args.runs}, {args.parallel}")
    if not (math.isfinite(args.duration) and args.duration > 0):
        ap.error(f"--duration must be a positive number of seconds, got {args.duration}")
    if not (math.isfinite(args.control_ms) and args.control_ms > 0):
        ap.error(f"--control-ms must be a positive number of ms, got {args.control_ms}")
    print(
        f"# {args.runs} run(s) of {args.duration:g} s, rig run --controller {args.controller} --control-ms "
        f"{args.control_ms:g} --omega-ref {args.omega_ref:g}, {args.parallel} side by side; "
        f"{os.cpu_count()} CPUs, load average at start {' '.join(f'{x:.2f}' for x in os.getloadavg())}",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="bench_rig_") as tmp:

        def one(k: int) -> RunResult:
            work = Path(tmp) / f"run{k}"
            work.mkdir()
            res = run_once(work, args.duration, args.control_ms, args.controller, args.omega_ref)
            load = " ".join(f"{x:.2f}" for x in os.getloadavg())
            print(f"run {k + 1}: {res.line()}; load average at end {load}", flush=True)
            return res

        with ThreadPoolExecutor(args.parallel) as pool:
            results = list(pool.map(one, range(args.runs)))
    print(f"total: {totals(results)}", flush=True)
    return 0 if all(r.completed for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
