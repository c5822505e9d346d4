"""Will a run fit? Memory and disk a ``drillgym simulate`` run needs, estimated before it starts.

A run of ``n`` steps keeps the per-step input (and its time grid) and ``n / record_every + 1``
recorded rows of every output column in memory, then writes them as CSV text (about 21
characters a value).  A run that would not fit is refused in one line naming the option to change,
instead of dying in a MemoryError traceback halfway.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..errors import InputError

__all__ = ["run_sizes", "available_memory", "check_run_fits"]

_CSV_COLUMNS = 13  # t, u, theta_u, theta_l, x, y, omega_u, omega_l, Tfu, Tfl, stick_l (+ margin)
_CHARS_PER_VALUE = 21


def _gb(n: float) -> str:
    return f"{n / 1e9:.3g} GB" if n < 1e12 else f"{n / 1e12:.3g} TB"


def run_sizes(duration: float, dt: float, record_every: int = 1) -> tuple[int, int, int]:
    """(steps, memory bytes, csv bytes) of one simulated run of ``duration`` s at step ``dt`` s."""
    from ..integrators import N_OUT

    n_steps = int(round(duration / dt))
    n_rec = n_steps // max(int(record_every), 1) + 1
    memory = 3 * 8 * n_steps + 8 * n_rec * (N_OUT + _CSV_COLUMNS)  # input, time grid, hold index; rows, csv copy
    return n_steps, memory, n_rec * _CSV_COLUMNS * _CHARS_PER_VALUE


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux MemAvailable), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _existing(path: Path) -> Path:
    p = path.resolve()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_run_fits(duration: float, dt: float, record_every: int, out: Path) -> None:
    """Refuse (ValueError, one line) a run whose arrays exceed 80 % of the available memory or whose
    CSV exceeds the free space where ``out`` goes.  Bad ``duration``/``dt`` are left to the simulator."""
    if not (duration > 0 and dt > 0) or duration == float("inf"):
        return
    how = "shorten --duration, or raise --dt or --record-every"
    if duration / dt == float("inf"):
        raise InputError(f"--duration {duration:g} s at --dt {dt:g} s is more steps than any memory holds: {how}")
    n_steps, memory, csv = run_sizes(duration, dt, record_every)
    avail = available_memory()
    if avail is not None and memory > 0.8 * avail:
        raise InputError(
            f"--duration {duration:g} s at --dt {dt:g} s ({n_steps:.3g} steps, --record-every "
            f"{record_every}) needs about {_gb(memory)} of memory, {_gb(avail)} available: {how}"
        )
    free = shutil.disk_usage(_existing(out.parent)).free
    if csv > free:
        raise InputError(f"--out {out}: the run's csv would take about {_gb(csv)}, {_gb(free)} free there: {how}")
