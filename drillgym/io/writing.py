"""Writing time series: a whole series, a simulated run, or rows streamed as they arrive."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO

import numpy as np

from ..configurations import Configuration
from ..errors import InputTypeError
from .jsonfile import dumps_json
from .paths import written_whole
from .timeseries import TimeSeries


def _fmt(v: float) -> str:
    return repr(float(v))


def write_timeseries(path: str | Path, ts: TimeSeries) -> Path:
    """Write a TimeSeries as CSV (docs/data_format.md; full float precision, round-trips exactly).

    Parameters
    ----------
    path : str or path
        Output file.
    ts : TimeSeries
        The series; its ``meta`` goes into the ``# meta:`` comment line.

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    OutputPathError
        The file cannot be written (missing directory, no permission, a full disk); an existing file
        is then left as it was.
    InputTypeError
        ``path`` is not a file's path (e.g. the arguments given the other way round).
    """
    if not isinstance(path, (str, os.PathLike)):
        swapped = " (the arguments are (path, ts))" if isinstance(path, TimeSeries) else ""
        raise InputTypeError(
            f"write_timeseries: path must be a file's path (text or path-like), got {type(path).__name__}{swapped}"
        )
    path = Path(path)
    names = list(ts.columns)
    meta = dumps_json(ts.meta)
    data = np.column_stack([ts.columns[n] for n in names])
    with written_whole(path, "the time series", newline="") as fh:
        fh.write(f"# meta: {meta}\n")
        fh.write(",".join(names) + "\n")
        for row in data:
            fh.write(",".join(_fmt(v) for v in row) + "\n")
    return path


def trajectory_to_timeseries(traj, description: str = "") -> TimeSeries:
    """A simulated Trajectory as a TimeSeries in the interchange columns."""
    cfg = traj.config
    cols = {"t": traj.t, "u": traj.u, "theta_u": traj.theta_u}
    if cfg is not Configuration.UPPER:
        cols["theta_l"] = traj.theta_l
    if cfg.lateral_free:
        cols["x"] = traj.x
        cols["y"] = traj.y
    cols["omega_u"] = traj.omega_u
    if cfg is not Configuration.UPPER:
        cols["omega_l"] = traj.omega_l
    cols["Tfu"] = traj.Tfu
    cols["Tfl"] = traj.Tfl
    cols["stick_l"] = traj.stick_l
    meta = {
        "configuration": cfg.label,
        "source": "simulation",
        "sample_rate_hz": 1.0 / (traj.t[1] - traj.t[0]) if len(traj.t) > 1 else None,
        "dt": traj.dt,
        "method": traj.method,
        "description": description,
    }
    return TimeSeries({k: np.asarray(v, dtype=float) for k, v in cols.items()}, meta, "<simulation>")


def write_trajectory_csv(traj, path: str | Path, description: str = "") -> Path:
    """Write a simulated run in the interchange format (so it compares with a measured one).

    Parameters
    ----------
    traj : Trajectory
        A run of :func:`drillgym.simulate`.
    path : str or path
        Output CSV file.
    description : str, optional
        Free text stored in the metadata.

    Returns
    -------
    Path
        The path written.
    """
    return write_timeseries(path, trajectory_to_timeseries(traj, description))


class StreamingCsvWriter:
    """Append rows to a CSV of docs/data_format.md as they arrive, flushed to disk in blocks.

    At most ``flush_interval_s`` of samples (by their ``t`` column) is held in
    memory, so a killed process loses at most that much.  Each flush ends with
    ``os.fsync``.  Use as a context manager; ``close()`` flushes the rest.

    Parameters
    ----------
    path : str or path
        The CSV file (overwritten).
    columns : sequence of str
        Column names, ``t`` among them.
    meta : mapping, optional
        Metadata written in the ``# meta:`` line.
    flush_interval_s : float, optional
        Longest time of samples held in memory (s, by the ``t`` column).  Default 0.5.
    """

    def __init__(
        self, path: str | Path, columns: Sequence[str], meta: Mapping | None = None, flush_interval_s: float = 0.5
    ) -> None:
        if "t" not in columns:
            raise ValueError("a recording needs a 't' column")
        self.path = Path(path)
        self.columns = list(columns)
        self.flush_interval_s = float(flush_interval_s)
        self._buf: list[str] = []
        self._t_last_flush: float | None = None
        self._fh: IO[str] | None = self.path.open("w", encoding="utf-8", newline="")
        self._fh.write(f"# meta: {dumps_json(dict(meta or {}))}\n")
        self._fh.write(",".join(self.columns) + "\n")
        self.flush()

    def write(self, row: Mapping[str, float] | Sequence[float]) -> None:
        """Append one row: a mapping by column name, or values in column order."""
        if self._fh is None:
            raise ValueError(f"{self.path}: recording already closed")
        if isinstance(row, Mapping):
            values = [row[c] for c in self.columns]
        else:
            values = list(row)
            if len(values) != len(self.columns):
                raise ValueError(f"row has {len(values)} values, recording has {len(self.columns)} columns")
        self._buf.append(",".join(_fmt(v) for v in values))
        t = float(values[self.columns.index("t")])
        if self._t_last_flush is None:
            self._t_last_flush = t
        if t - self._t_last_flush >= self.flush_interval_s:
            self.flush()
            self._t_last_flush = t

    def write_many(self, rows: Iterable[Sequence[float]]) -> None:
        """Append rows of values in column order."""
        for r in rows:
            self.write(r)

    def flush(self) -> None:
        """Write the held rows and ``fsync`` the file."""
        if self._fh is None:
            return
        if self._buf:
            self._fh.write("\n".join(self._buf) + "\n")
            self._buf.clear()
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        """Flush the rest and close the file (idempotent)."""
        if self._fh is not None:
            self.flush()
            self._fh.close()
            self._fh = None

    def __enter__(self) -> StreamingCsvWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
