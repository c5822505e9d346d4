"""Metrics of a closed-loop run (steady state = the last ``window`` seconds).

* SSI, stick-slip severity: (max omega_l - min omega_l) / (2 mean omega_l); infinite when the
  lower disc does not turn on average (mean omega_l <= 1 % of the target).
* stuck: fraction of the steady window the lower disc sticks.
* tracking_rms: RMS of omega_l - omega_ref over the steady window (rad/s).
* u_peak, u_rms: peak and RMS voltage over the whole run (V).
* energy: mechanical work of the motor, integral of km u omega_u dt over the whole run (J).
* stick_slip: SSI >= 0.1 (the harness's criterion).
* offset: (mean omega_l - omega_ref) / omega_ref over the steady window; a target counts as *held*
  only when SSI < 0.1 and |offset| <= TRACKING_TOLERANCE (a smooth rotation at another speed is
  not holding the target).
* omega_l_min, omega_l_max, u_mean: steady-state range of omega_l (rad/s) and mean voltage (V).
* speed_peak: largest |omega_u| or |omega_l| over the whole run (rad/s); runaway: speed_peak above the
  rig's over-speed stop :data:`SAFETY_SPEED` (a controller must never get there on a slightly-off rig).
* whirl: 95th percentile of the lateral displacement r = sqrt(x^2 + y^2) of the lower disc's centre over the
  steady window, relative to the rig's lateral over-displacement stop :data:`LATERAL_STOP` (20 mm;
  dimensionless, 0 with the constraints clamped, 1: the disc reaches the stop).
"""

from __future__ import annotations

import numpy as np

from drillgym import RigParams
from drillgym.errors import InputError

__all__ = [
    "SSI_THRESHOLD",
    "TRACKING_TOLERANCE",
    "SAFETY_SPEED",
    "LATERAL_STOP",
    "METRICS",
    "stick_slip_severity",
    "run_metrics",
    "lowest_free_speed",
]

SSI_THRESHOLD = 0.1
TRACKING_TOLERANCE = 0.1  # relative offset of the mean lower-disc speed from the target
SAFETY_SPEED = 40.0  # rad/s, the rig's over-speed stop (hw.safety.SafetyLimits.max_speed)
LATERAL_STOP = 0.02  # m, the rig's lateral over-displacement stop (hw.safety.SafetyLimits.max_displacement)
METRICS = (
    "ssi",
    "stuck",
    "tracking_rms",
    "u_peak",
    "u_rms",
    "energy",
    "stick_slip",
    "omega_l_min",
    "omega_l_max",
    "u_mean",
    "offset",
    "speed_peak",
    "runaway",
    "whirl",
)


def stick_slip_severity(omega_l: np.ndarray, omega_ref: float | np.ndarray | None = None) -> np.ndarray:
    """Stick-slip severity (max omega_l - min omega_l) / (2 mean omega_l) of each run.

    Parameters
    ----------
    omega_l : ndarray
        Lower-disc speed (rad/s), one run per row (n, m) or one run (m,).
    omega_ref : float or ndarray, optional
        Target speed(s) (rad/s): a mean below 1 % of it counts as standing still.  Default: 1 % of 1 rad/s.

    Returns
    -------
    ndarray or float
        SSI (dimensionless) per row, or of the one run; inf when the disc stands still on average.
    """
    w = np.atleast_2d(np.asarray(omega_l, dtype=float))
    mean = w.mean(axis=1)
    floor = 1e-2 * (np.abs(np.broadcast_to(omega_ref, mean.shape)) if omega_ref is not None else 1.0)
    ssi = np.where(
        mean > np.maximum(floor, 1e-9), (w.max(axis=1) - w.min(axis=1)) / (2 * np.where(mean > 0, mean, 1)), np.inf
    )
    return ssi if np.ndim(omega_l) == 2 else ssi[0]


def run_metrics(run, window: float, params: RigParams | None = None) -> dict[str, np.ndarray]:
    """Metrics (each an (n,) array) of a :class:`controllers.evaluation.runner.ClosedLoopRun`."""
    p = params or RigParams()
    if not (0 < window <= run.t[-1] + run.dt):
        raise InputError(f"steady-state window must be in (0, {run.t[-1] + run.dt:.3g}] s, got {window!r}")
    ss = run.t >= run.t[-1] + run.dt - window
    wl = run.omega_l[:, ss]
    ssi = stick_slip_severity(wl, run.omega_ref)
    peak = np.maximum(np.abs(run.omega_u).max(axis=1), np.abs(run.omega_l).max(axis=1))
    return {
        "ssi": ssi,
        "stuck": run.stuck_l[:, ss].mean(axis=1),
        "tracking_rms": np.sqrt(np.mean((wl - run.omega_ref[:, None]) ** 2, axis=1)),
        "u_peak": np.abs(run.u).max(axis=1),
        "u_rms": np.sqrt(np.mean(run.u**2, axis=1)),
        "energy": np.sum(p.km * run.u * run.omega_u, axis=1) * run.dt,
        "stick_slip": ssi >= SSI_THRESHOLD,
        "omega_l_min": wl.min(axis=1),
        "omega_l_max": wl.max(axis=1),
        "u_mean": run.u[:, ss].mean(axis=1),
        "offset": (wl.mean(axis=1) - run.omega_ref) / run.omega_ref,
        "speed_peak": peak,
        "runaway": peak > SAFETY_SPEED,
        "whirl": np.quantile(run.r[:, ss], 0.95, axis=1) / LATERAL_STOP,
    }


def lowest_free_speed(
    targets: np.ndarray,
    ssi: np.ndarray,
    threshold: float = SSI_THRESHOLD,
    offset: np.ndarray | None = None,
    tolerance: float = TRACKING_TOLERANCE,
    whirl: np.ndarray | None = None,
    whirl_threshold: float | None = None,
) -> float:
    """Lowest target from which every higher target of the grid is held.

    A target is held when it shows no stick-slip (SSI < ``threshold``), when ``offset`` is given, its mean
    speed is within ``tolerance`` of the target and, when ``whirl`` is given, its whirl is below
    ``whirl_threshold``.

    Parameters
    ----------
    targets : ndarray
        Target speeds of the grid (rad/s), any order.
    ssi : ndarray
        Stick-slip severity at each target.
    threshold : float, optional
        SSI below which a run shows no stick-slip.  Default 0.1.
    offset : ndarray, optional
        Relative offset (mean omega_l - target) / target at each target.
    tolerance : float, optional
        Largest |offset| of a held target.  Default 0.1.
    whirl : ndarray, optional
        Whirl at each target (dimensionless, the ``whirl`` metric of :func:`run_metrics`).
    whirl_threshold : float, optional
        Whirl from which a target is not held; needed with ``whirl``.

    Returns
    -------
    float
        The lowest held target (rad/s); NaN when the highest one is not held.
    """
    t = np.asarray(targets, dtype=float)
    order = np.argsort(t)[::-1]
    held = np.asarray(ssi, dtype=float) < threshold
    if offset is not None:
        held &= np.abs(np.asarray(offset, dtype=float)) <= tolerance
    if whirl is not None:
        if whirl_threshold is None:
            raise InputError("lowest_free_speed: whirl needs a whirl_threshold")
        held &= np.asarray(whirl, dtype=float) < whirl_threshold
    ok = held[order]
    if not ok[0]:
        return float("nan")
    k = len(ok) if ok.all() else int(np.argmin(ok))
    return float(t[order][k - 1])
