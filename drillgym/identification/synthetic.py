"""Synthetic "measurements": a simulated run passed through the rig's measurement chain.

Used by the tests, the benchmark and demos: the model (optionally with hidden
effects, ``effects=[...]``, the library's or a user's) is driven by an excitation
signal, and the run is measured like the rig does it
(:func:`drillgym.measurement.measure_trajectory`: the effects' measurement
transformations, encoder quantization, LVDT noise, 5 Hz zero-phase low-pass).
The ``u`` column holds the *commanded* voltage at each sample time (what a
rig recording holds), not the simulator's delayed or lagged internal input.
"""

from __future__ import annotations

from dataclasses import replace as _dc_replace
from typing import Any, Callable, Mapping

import numpy as np

from ..effects import compose
from ..io import TimeSeries
from ..measurement import MeasurementModel, measure_trajectory
from ..params import RigParams
from ..signals import quasi_random, sum_of_sines
from ..simulator import simulate

__all__ = ["synthetic_measurement", "BEARING"]

_LOWER_LEVEL = ("Tcl", "bl", "Ts", "Tc", "bb")

BEARING = "torsional_bearing"  # torsional system with the brake off (identification stage 2b)


def synthetic_measurement(config: str, params: RigParams | None = None, *, duration: float = 30.0,
                          rate_hz: float = 500.0, signal: str = "quasi_random", offset: float = 1.0,
                          amplitude: float = 5.0, seed: int = 0, alpha0: float = 0.0, dt: float = 1e-3,
                          model: MeasurementModel = MeasurementModel(), u: float | None = None,
                          input: tuple[np.ndarray, np.ndarray] | None = None,
                          level_profile: Callable[[float], float] | None = None,
                          level_chunk_s: float = 1.0, effects: Any = None,
                          effect_params: Mapping[str, float] | None = None) -> TimeSeries:
    """Simulate ``config`` with ``params`` (default MODEL.md) and measure it.

    ``config`` may also be ``"torsional_bearing"``: lateral motion held, brake off (simulated
    exactly as ``lateral`` with e = 0; the file says configuration 'torsional', brake force 0).

    Args:
        signal: 'quasi_random' (estimation), 'sum_of_sines' (validation) or 'steps' (unfiltered random
            levels held 2-6 s, ``offset ± amplitude``); ``u`` (V) instead gives a constant input and
            ``input`` = (t, u) arrays (s, V) any recorded input (zero-order hold, resampled to the record).
        offset, amplitude: signal mean and half range (V).
        rate_hz: sample rate of the measurement (Hz); ``dt`` the simulator step (s).
        alpha0: initial winding (rad).
        level_profile: optional factor g(t) (g(0) = 1) on the lower friction level (Tcl, bl, Ts, Tc, bb),
            a friction drift of any form in time (e.g. saturating warm-up): simulated in chunks of
            ``level_chunk_s`` seconds, each continuing from the previous one's final state with g
            interpolated linearly across the chunk (the kernel's own drift term).  Not combinable
            with effects that carry a state or a delay (those act relative to a run's start).
        effects, effect_params: hidden effects of the simulated rig and their parameter values
            (as :func:`drillgym.simulate`), e.g. ``effects=["string_damping"], effect_params={"dtheta": 0.01}``.
    """
    p = params or RigParams()
    rec = max(1, int(round(1.0 / (rate_hz * dt))))
    fs = 1.0 / (rec * dt)
    if input is not None:
        t_in, u_in = (np.asarray(a, dtype=float) for a in input)
        if t_in.ndim != 1 or t_in.shape != u_in.shape or t_in.size < 2:
            raise ValueError("input must be two 1-D arrays (t, u) of one length >= 2")
        t = np.arange(int(round(duration * fs)) + 1) / fs
        uu = u_in[np.clip(np.searchsorted(t_in, t, side="right") - 1, 0, t_in.size - 1)]
        signal = "custom"
    elif u is not None:
        t = np.arange(int(round(duration * fs)) + 1) / fs
        uu = np.full_like(t, float(u))
    elif signal == "steps":
        t = np.arange(int(round(duration * fs)) + 1) / fs
        rng = np.random.default_rng(seed)
        uu = np.empty_like(t)
        i = 0
        while i < t.size:
            k = max(1, int(rng.uniform(2.0, 6.0) * fs))
            uu[i:i + k] = offset + (amplitude - abs(offset)) * rng.uniform(-1.0, 1.0)
            i += k
    elif signal == "quasi_random":
        t, uu = quasi_random(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    elif signal == "sum_of_sines":
        t, uu = sum_of_sines(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    else:
        raise ValueError(f"unknown signal {signal!r}; expected 'quasi_random', 'sum_of_sines' or 'steps'")
    bearing = config == BEARING
    sim_p = p.replace(e=0.0) if bearing else p
    comp, values = compose(effects, effect_params)
    if level_profile is None:
        traj = simulate("lateral" if bearing else config, (t, uu), duration, dt=dt, params=sim_p, alpha0=alpha0,
                        method="dp5", record_every=rec, effects=comp, effect_params=values)
    else:
        traj = _simulate_level_profile("lateral" if bearing else config, t, uu, duration, dt, sim_p, alpha0, rec,
                                       level_profile, level_chunk_s, comp, values)
    ts = measure_trajectory(traj, model, seed=seed)
    if bearing:  # lateral motion held, brake off: no LVDT channels
        ts.columns.pop("x", None)
        ts.columns.pop("y", None)
        ts.meta.update(configuration="torsional", brake_normal_force_n=0.0)
    ts.columns["u"] = np.interp(ts.t, t, uu)
    ts.meta["description"] = f"synthetic {signal if u is None or input is not None else 'constant'} input"
    return ts


def _simulate_level_profile(config: str, t: np.ndarray, uu: np.ndarray, duration: float, dt: float, p: RigParams,
                            alpha0: float, rec: int, g: Callable[[float], float], chunk_s: float, comp, values):
    """A run whose lower friction level follows g(t): chunks continued from the previous final state
    (the library's friction_drift, added to the composition, interpolates g across each chunk)."""
    if comp.has_delay or comp.n_states or "friction_drift" in comp.names:
        raise ValueError("level_profile cannot be combined with friction_drift or effects with a delay or a state "
                         "(they act from a run's start)")
    chunk_comp, _ = compose(list(comp.effects) + ["friction_drift"])
    if abs(float(g(0.0)) - 1.0) > 1e-9:
        raise ValueError("level_profile must satisfy g(0) = 1")
    fs = 1.0 / (rec * dt)
    n_chunk = max(1, int(round(chunk_s * fs)))  # samples per chunk
    n_total = int(round(duration * fs))
    blocks, x0, k0 = [], None, 0
    while k0 < n_total:
        k1 = min(k0 + n_chunk, n_total)
        t0, t1 = k0 / fs, k1 / fs
        g0, g1 = float(g(t0)), float(g(t1))
        if g0 <= 0 or g1 <= 0:
            raise ValueError(f"level_profile must stay positive (g({t0:g}) = {g0:g}, g({t1:g}) = {g1:g})")
        pc = p.replace(**{n: getattr(p, n) * g0 for n in _LOWER_LEVEL})
        drift = (g1 / g0 - 1.0) / (t1 - t0)
        sel = (t >= t0 - 1e-12) & (t <= t1 + 1.0 / fs + 1e-12)
        tr = simulate(config, (t[sel] - t0, uu[sel]), t1 - t0, dt=dt, params=pc, alpha0=alpha0, x0=x0,
                      method="dp5", record_every=rec, effects=chunk_comp, effect_params={**values, "drift": drift})
        data = tr.data.copy()
        data[:, 0] += t0
        blocks.append(data if not blocks else data[1:])
        x0 = tr.final_state
        k0 = k1
    return _dc_replace(tr, params=p, data=np.concatenate(blocks), composition=comp, effect_values=dict(values))
