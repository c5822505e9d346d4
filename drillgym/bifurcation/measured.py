"""Measured bifurcation diagrams: steady-state statistics of constant-voltage measurement files,
and the measured points the report gives (docs/model.md), as an overlay."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from ..errors import DataFormatError
from ..io import read_timeseries
from .steady_state import STAT_NAMES, stats_from_arrays

# measured points of the report (docs/model.md, "Measured bifurcation points"), voltages in V, speeds in rad/s
REPORT_POINTS: dict[str, dict] = {
    "torsional": {"hopf": [1.7], "fold": [4.0], "coexistence": [{"u": 3.6, "omega_eq": 6.25}]},
    "coupled": {"hopf": [1.6], "fold": [3.5], "coexistence": [{"u": 3.4, "omega_eq": None}]},
    "lateral": {"hopf": [], "fold": [], "coexistence": []},
}
SETTLE_FRACTION = 0.5  # the first half of a constant-voltage run is treated as transient
CONSTANT_VOLTAGE_TOL = 0.02  # V


def measured_point(path: str | Path, config: str | None = None, settle_fraction: float = SETTLE_FRACTION) -> dict:
    """Steady-state statistics of one constant-voltage measurement.

    omega_l is taken from the file or differentiated from theta_l (Savitzky-Golay, 50 ms window).

    Parameters
    ----------
    path : str or path
        A time-series file (docs/data_format.md) of a run at constant voltage.
    config : str, optional
        Rig configuration, when the file's metadata names none.
    settle_fraction : float, optional
        Leading fraction of the run treated as transient.  Default 0.5.

    Returns
    -------
    dict
        ``u`` (V) and the steady-state quantities ``omega_l_min``, ``omega_l_max`` (rad/s), ``r_min``,
        ``r_max`` (m), ``period`` (s, NaN when not oscillating), ``stick_fraction``.
    """
    ts = read_timeseries(path, config)
    n = len(ts)
    i0 = int(n * settle_fraction)
    if n - i0 < 10:
        raise DataFormatError(f"{path}: too few samples ({n}) for a steady-state window")
    u = np.asarray(ts.u[i0:])
    if np.ptp(u) > CONSTANT_VOLTAGE_TOL:
        raise DataFormatError(
            f"{path}: column u is not constant in the steady-state window "
            f"(range {np.ptp(u):.3g} V); a bifurcation point needs a constant voltage"
        )
    t = np.asarray(ts.t)
    if "omega_l" in ts:
        w = np.asarray(ts.omega_l)
    elif "theta_l" in ts:
        win = max(5, int(0.05 * ts.sample_rate_hz) | 1)
        w = savgol_filter(np.asarray(ts.theta_l), win, 2, deriv=1, delta=float(np.median(np.diff(t))))
    else:
        raise DataFormatError(f"{path}: needs column theta_l or omega_l for a bifurcation point")
    r = ts.r
    st = stats_from_arrays(t[i0:], w[i0:], None if r is None else np.asarray(r)[i0:])
    return {"file": str(path), "u": float(np.mean(u)), **{k: float(v) for k, v in zip(STAT_NAMES, st)}}


def measured_diagram(paths: Sequence[str | Path], config: str | None = None) -> list[dict]:
    """:func:`measured_point` of every file, sorted by voltage.

    Parameters
    ----------
    paths : sequence of str or path
        Constant-voltage measurement files.
    config : str, optional
        Rig configuration, when a file's metadata names none.

    Returns
    -------
    list of dict
        One point per file, sorted by voltage ``u`` (V).
    """
    return sorted((measured_point(p, config) for p in paths), key=lambda d: d["u"])
