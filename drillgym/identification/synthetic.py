"""Synthetic "measurements": a simulated run passed through the rig's measurement chain.

Used by the tests, the benchmark and demos: the model (optionally with a
hidden effect switched on) is driven by an excitation signal, and the run is
measured like the rig does it (:func:`drillgym.measurement.measure_trajectory`:
encoder quantization, LVDT noise, offsets/skew, 5 Hz zero-phase low-pass).
The ``u`` column holds the *commanded* voltage at each sample time (what a
rig recording holds), not the simulator's delayed or lagged internal input.
"""

from __future__ import annotations

import numpy as np

from ..io import TimeSeries
from ..measurement import MeasurementModel, measure_trajectory
from ..params import RigParams
from ..signals import quasi_random, sum_of_sines
from ..simulator import simulate

__all__ = ["synthetic_measurement", "BEARING"]

BEARING = "torsional_bearing"  # torsional system with the brake off (identification stage 2b)


def synthetic_measurement(config: str, params: RigParams | None = None, *, duration: float = 30.0,
                          rate_hz: float = 500.0, signal: str = "quasi_random", offset: float = 1.0,
                          amplitude: float = 5.0, seed: int = 0, alpha0: float = 0.0, dt: float = 1e-3,
                          model: MeasurementModel = MeasurementModel(), u: float | None = None) -> TimeSeries:
    """Simulate ``config`` with ``params`` (default MODEL.md) and measure it.

    ``config`` may also be ``"torsional_bearing"``: lateral motion held, brake off (simulated
    exactly as ``lateral`` with e = 0; the file says configuration 'torsional', brake force 0).

    Args:
        signal: 'quasi_random' (estimation) or 'sum_of_sines' (validation); ``u`` (V) instead gives a constant input.
        offset, amplitude: signal mean and half range (V).
        rate_hz: sample rate of the measurement (Hz); ``dt`` the simulator step (s).
        alpha0: initial winding (rad).
    """
    p = params or RigParams()
    rec = max(1, int(round(1.0 / (rate_hz * dt))))
    fs = 1.0 / (rec * dt)
    if u is not None:
        t = np.arange(int(round(duration * fs)) + 1) / fs
        uu = np.full_like(t, float(u))
    elif signal == "quasi_random":
        t, uu = quasi_random(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    elif signal == "sum_of_sines":
        t, uu = sum_of_sines(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    else:
        raise ValueError(f"unknown signal {signal!r}; expected 'quasi_random' or 'sum_of_sines'")
    bearing = config == BEARING
    sim_p = p.replace(e=0.0) if bearing else p
    traj = simulate("lateral" if bearing else config, (t, uu), duration, dt=dt, params=sim_p, alpha0=alpha0,
                    method="dp5", record_every=rec)
    ts = measure_trajectory(traj, sim_p, model, seed=seed)
    if bearing:  # lateral motion held, brake off: no LVDT channels
        ts.columns.pop("x", None)
        ts.columns.pop("y", None)
        ts.meta.update(configuration="torsional", brake_normal_force_n=0.0)
    ts.columns["u"] = np.interp(ts.t, t, uu)
    ts.meta["description"] = f"synthetic {signal if u is None else 'constant'} input"
    return ts
