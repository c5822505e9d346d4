"""Timing statistics of a real-time loop that allocate nothing while they count.

:class:`DurationStats` counts durations in a fixed histogram (0.01 ms bins up to 1 s), so
percentiles of millions of replies cost a few kilobytes and no allocation in the loop;
:class:`GcPauses` times the garbage collector's pauses with :data:`gc.callbacks`.  The rig
emulator reports both when it stops (``drillgym rig emulate``), ``drillgym rig run`` reports
the host's reply times, and ``benchmarks/bench_rig_reply_times.py`` collects them over long runs.
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["DurationStats", "GcPauses", "PERCENTILES", "percentile_summary"]

#: the percentiles reported for reply and service times
PERCENTILES = (50.0, 90.0, 99.0, 99.9)
_BIN_S = 1e-5  # histogram resolution (s)
_N_BINS = 100_000  # up to 1 s; longer durations go to the last bin (their maximum is kept exactly)


class DurationStats:
    """Count durations (s) in a preallocated histogram; percentiles to 0.01 ms, the maximum exactly."""

    def __init__(self) -> None:
        self.hist = np.zeros(_N_BINS, dtype=np.int64)
        self.count = 0
        self.max = 0.0
        self.max_at = 0.0  # time.monotonic of the longest one's end

    def add(self, seconds: float, at: float = 0.0) -> None:
        """Count one duration (s) that ended at ``at`` (s, time.monotonic)."""
        k = int(seconds / _BIN_S)
        self.hist[min(max(k, 0), _N_BINS - 1)] += 1
        self.count += 1
        if seconds > self.max:
            self.max, self.max_at = seconds, at

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile (s, upper edge of its bin; the maximum for the last sample); NaN when empty."""
        if self.count == 0:
            return float("nan")
        rank = int(np.ceil(q / 100.0 * self.count))
        k = int(np.searchsorted(np.cumsum(self.hist), max(rank, 1)))
        return min((k + 1) * _BIN_S, self.max)

    def summary(self) -> str:
        """``p50 a, p90 b, p99 c, p99.9 d, max e ms`` (no samples: ``none``)."""
        if self.count == 0:
            return "none"
        return percentile_summary([self.percentile(q) for q in PERCENTILES], self.max)


def percentile_summary(values_s, max_s: float) -> str:
    """``p50 a, p90 b, p99 c, p99.9 d, max e ms`` from the :data:`PERCENTILES` values and the maximum (s)."""
    parts = [f"p{q:g} {1e3 * v:.2f}" for q, v in zip(PERCENTILES, values_s)]
    return ", ".join(parts) + f", max {1e3 * max_s:.2f} ms"


@dataclass
class _Pause:
    count: int = 0
    longest: float = 0.0
    generation: int = -1


class GcPauses:
    """Time the garbage collector's pauses while installed (``with GcPauses() as p:`` or install/remove)."""

    def __init__(self) -> None:
        self._start = 0.0
        self.pauses = _Pause()
        self.over_1ms = 0

    def _callback(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._start = time.perf_counter()
            return
        d = time.perf_counter() - self._start
        self.pauses.count += 1
        if d > 1e-3:
            self.over_1ms += 1
        if d > self.pauses.longest:
            self.pauses.longest, self.pauses.generation = d, int(info.get("generation", -1))

    def install(self) -> GcPauses:
        """Start timing (appends to :data:`gc.callbacks`)."""
        if self._callback not in gc.callbacks:
            gc.callbacks.append(self._callback)
        return self

    def remove(self) -> None:
        """Stop timing."""
        if self._callback in gc.callbacks:
            gc.callbacks.remove(self._callback)

    def __enter__(self) -> GcPauses:
        return self.install()

    def __exit__(self, *exc) -> None:
        self.remove()

    def summary(self) -> str:
        """``N collections, longest X ms (generation G), M over 1 ms``."""
        p = self.pauses
        if p.count == 0:
            return "no collections"
        return (
            f"{p.count} collections, longest {1e3 * p.longest:.2f} ms (generation {p.generation}), "
            f"{self.over_1ms} over 1 ms"
        )
