"""The reply-time benchmark (benchmarks/bench_rig_reply_times.py) and the timing it reads: percentiles from the
preallocated histogram agree with numpy's, the benchmark reads what `rig run` and `rig emulate` print, and its
smoke mode runs one short emulator + host pair end to end without a stop."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hw.emulator import RigEmulator
from hw.timing import PERCENTILES, DurationStats, GcPauses, percentile_summary

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.xdist_group("rig-realtime")  # real-time emulator and host: one such worker at a time


def _bench():
    path = ROOT / "benchmarks" / "bench_rig_reply_times.py"
    spec = importlib.util.spec_from_file_location("bench_rig_reply_times", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_histogram_percentiles_agree_with_numpy():
    rng = np.random.default_rng(1)
    x = rng.lognormal(np.log(5e-4), 0.6, 20_000)
    x[123] = 0.25  # one outlier: the maximum is exact
    st = DurationStats()
    for v in x:
        st.add(float(v))
    assert st.count == x.size and st.max == x.max()
    for q in PERCENTILES:
        # nearest rank, to one 0.01 ms bin
        assert st.percentile(q) == pytest.approx(np.percentile(x, q, method="inverted_cdf"), abs=1e-5 + 1e-12)
    assert math.isnan(DurationStats().percentile(50)) and DurationStats().summary() == "none"


def test_gc_pauses_are_timed():
    import gc

    with GcPauses() as p:
        gc.collect()
    assert p.pauses.count >= 1 and p.pauses.longest > 0 and p.pauses.generation == 2
    assert "collections, longest" in p.summary()


def test_benchmark_reads_what_the_commands_print():
    bench = _bench()
    rt = np.array([4e-4, 5e-4, 6e-4, 9e-3])
    host_out = (
        "30000 steps, return -1.00, truncated\n"
        f"reply time (command sent -> its SAMPLE received) over 30000 commands: "
        f"{percentile_summary(np.percentile(rt, PERCENTILES), rt.max())}; tick error p99 0.70 ms\n"
    )
    emu = RigEmulator("torsional", dt=5e-3)
    for v in (3e-4, 4e-4, 7.5e-3):
        emu.service.add(v)
    emu.gc_pauses.pauses.count, emu.gc_pauses.pauses.longest, emu.gc_pauses.pauses.generation = 3, 1.5e-3, 0
    log = f"[21:00:00] emulator stopped: {emu.timing_summary()}\n"
    ok = subprocess.CompletedProcess([], 0, host_out, "")
    res = bench._result(ok, log, 61.0)
    assert res.completed and res.commands == 30000 and res.stop is None
    assert res.reply_ms["max"] == pytest.approx(9.0) and res.reply_ms["p50"] == pytest.approx(0.55)
    assert res.service_max_ms == pytest.approx(7.5) and res.gc_longest_ms == pytest.approx(1.5)
    stopped = subprocess.CompletedProcess(
        [], 3, "100 steps, return -1.00, stopped\n", "drillgym: safety stop: /tmp/rig: no SAMPLE reply ...\n"
    )
    res2 = bench._result(stopped, log, 2.0)
    assert not res2.completed and "exit 3" in res2.stop and "no SAMPLE reply" in res2.stop and res2.commands == 100
    assert "1 completed, 1 stopped" in bench.totals([res, res2]) and "STOPPED" in res2.line()
    silent = subprocess.CompletedProcess([], 3, "", "drillgym: safety stop: /tmp/rig: no SAMPLE reply ...\n")
    assert bench._result(silent, log, 2.0).commands == 3  # no summary from the host: the emulator's count


@pytest.mark.slow
def test_smoke_mode_runs_one_short_pair(tmp_path):
    p = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_rig_reply_times.py"), "--runs", "1", "--duration", "2"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    out = p.stdout
    assert p.returncode == 0, (out, p.stderr)
    run_line = next(ln for ln in out.splitlines() if ln.startswith("run 1:"))
    assert "completed; 1000 commands; reply time p50" in run_line and "emulator worst service time" in run_line
    assert "longest steal burst" in run_line and "logs kept" not in run_line  # a completed run keeps nothing
    assert "1 runs: 1 completed, 0 stopped" in out
