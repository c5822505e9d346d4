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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..effects import compose
from ..errors import InputError
from ..io import TimeSeries
from ..measurement import MeasurementModel, measure_trajectory
from ..params import RigParams
from ..signals import quasi_random, sum_of_sines
from ..simulator import simulate_batch

__all__ = ["SyntheticOptions", "synthetic_measurement", "BEARING"]

_LOWER_LEVEL = ("Tcl", "bl", "Ts", "Tc", "bb")

BEARING = "torsional_bearing"  # torsional system with the brake off (identification stage 2b)


@dataclass(frozen=True)
class SyntheticOptions:
    """How :func:`synthetic_measurement` drives, simulates and measures the rig.

    Attributes
    ----------
    duration : float
        Length of the run (s).  Default 30.
    rate_hz : float
        Sample rate of the measurement (Hz).  Default 500.
    signal : str
        ``'quasi_random'`` (estimation), ``'sum_of_sines'`` (validation) or ``'steps'`` (unfiltered random
        levels held 2-6 s, ``offset ± amplitude``).
    offset, amplitude : float
        The signal's mean and half range (V).  Defaults 1 and 5.
    seed : int
        Random seed of the signal and the measurement noise.  Default 0.
    alpha0 : float
        Initial winding (rad).  Default 0.
    dt : float
        Simulator step (s).  Default 1e-3.
    model : MeasurementModel
        The measurement chain.
    u : float or None
        A constant input (V) instead of ``signal``.
    input : tuple of (numpy.ndarray, numpy.ndarray) or None
        (t, u) arrays (s, V): any recorded input instead (zero-order hold, resampled to the record).
    level_profile : callable or None
        A factor g(t) (g(0) = 1) on the lower friction level (Tcl, bl, Ts, Tc, bb), a friction drift of any
        form in time (e.g. saturating warm-up): simulated in chunks of ``level_chunk_s`` seconds, each
        continuing from the previous one's final state with g interpolated linearly across the chunk (the
        kernel's own drift term).  Not combinable with effects that carry a state or a delay (those act
        relative to a run's start).
    level_chunk_s : float
        Chunk length with ``level_profile`` (s).  Default 1.
    effects : any
        Hidden effects of the simulated rig (as :func:`drillgym.simulate`), e.g. ``["string_damping"]``.
    effect_params : mapping of str to float or None
        Their parameter values, e.g. ``{"dtheta": 0.01}``.
    """

    duration: float = 30.0
    rate_hz: float = 500.0
    signal: str = "quasi_random"
    offset: float = 1.0
    amplitude: float = 5.0
    seed: int = 0
    alpha0: float = 0.0
    dt: float = 1e-3
    model: MeasurementModel = MeasurementModel()
    u: float | None = None
    input: tuple[np.ndarray, np.ndarray] | None = None
    level_profile: Callable[[float], float] | None = None
    level_chunk_s: float = 1.0
    effects: Any = None
    effect_params: Mapping[str, float] | None = None


def synthetic_measurement(
    config: str, params: RigParams | None = None, *, options: SyntheticOptions | None = None, **settings: Any
) -> TimeSeries:
    """Simulate a configuration of the rig and measure it.

    Parameters
    ----------
    config : str
        ``"upper"``, ``"torsional"``, ``"lateral"``, ``"coupled"``, ``"free_vibration"``, or
        ``"torsional_bearing"``: lateral motion held, brake off (simulated exactly as ``lateral`` with
        e = 0; the file says configuration 'torsional', brake force 0).
    params : RigParams, optional
        The rig's parameters (default: the identified set of docs/model.md).
    options : SyntheticOptions, optional
        How to drive, simulate and measure it (default: :class:`SyntheticOptions` ()).
    **settings
        Fields of :class:`SyntheticOptions` (``duration``, ``rate_hz``, ``signal``, ``offset``, ``amplitude``,
        ``seed``, ``alpha0``, ``dt``, ``model``, ``u``, ``input``, ``level_profile``, ``level_chunk_s``,
        ``effects``, ``effect_params``), overriding ``options``.

    Returns
    -------
    TimeSeries
        The measured recording.

    Raises
    ------
    InputError
        An unknown signal, a malformed input, or a level profile that cannot be used.
    """
    o = replace(options or SyntheticOptions(), **settings)
    p = params or RigParams()
    rec = max(1, int(round(1.0 / (o.rate_hz * o.dt))))
    fs = 1.0 / (rec * o.dt)
    t, uu, signal = _input(o, fs)
    bearing = config == BEARING
    sim_p = p.replace(e=0.0) if bearing else p
    comp, values = compose(o.effects, o.effect_params)
    if o.level_profile is None:
        traj = simulate_batch(
            "lateral" if bearing else config,
            (t, uu),
            o.duration,
            dt=o.dt,
            params=sim_p,
            alpha0=o.alpha0,
            method="dp5",
            record_every=rec,
            effects=comp,
            effect_params=values,
            n_batch=1,
        )[0]  # any duration and rate: simulate() would refuse a record interval that does not divide the run
    else:
        traj = _simulate_level_profile("lateral" if bearing else config, t, uu, o, sim_p, rec, comp, values)
    ts = measure_trajectory(traj, o.model, seed=o.seed)
    if bearing:  # lateral motion held, brake off: no LVDT channels
        ts.columns.pop("x", None)
        ts.columns.pop("y", None)
        ts.meta.update(configuration="torsional", brake_normal_force_n=0.0)
    ts.columns["u"] = np.interp(ts.t, t, uu)
    ts.meta["description"] = f"synthetic {signal if o.u is None or o.input is not None else 'constant'} input"
    return ts


def _input(o: SyntheticOptions, fs: float) -> tuple[np.ndarray, np.ndarray, str]:
    """(t, u, the signal's name) of the run's input at ``fs``."""
    duration, seed, offset, amplitude, signal = o.duration, o.seed, o.offset, o.amplitude, o.signal
    if o.input is not None:
        t_in, u_in = (np.asarray(a, dtype=float) for a in o.input)
        if t_in.ndim != 1 or t_in.shape != u_in.shape or t_in.size < 2:
            raise InputError("input must be two 1-D arrays (t, u) of one length >= 2")
        t = np.arange(int(round(duration * fs)) + 1) / fs
        uu = u_in[np.clip(np.searchsorted(t_in, t, side="right") - 1, 0, t_in.size - 1)]
        signal = "custom"
    elif o.u is not None:
        t = np.arange(int(round(duration * fs)) + 1) / fs
        uu = np.full_like(t, float(o.u))
    elif signal == "steps":
        t = np.arange(int(round(duration * fs)) + 1) / fs
        rng = np.random.default_rng(seed)
        uu = np.empty_like(t)
        i = 0
        while i < t.size:
            k = max(1, int(rng.uniform(2.0, 6.0) * fs))
            uu[i : i + k] = offset + (amplitude - abs(offset)) * rng.uniform(-1.0, 1.0)
            i += k
    elif signal == "quasi_random":
        t, uu = quasi_random(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    elif signal == "sum_of_sines":
        t, uu = sum_of_sines(duration, rate_hz=fs, seed=seed, amplitude=amplitude, offset=offset)
    else:
        raise InputError(f"unknown signal {signal!r}; expected 'quasi_random', 'sum_of_sines' or 'steps'")
    return t, uu, signal


def _simulate_level_profile(
    config: str, t: np.ndarray, uu: np.ndarray, o: SyntheticOptions, p: RigParams, rec: int, comp, values
):
    """A run whose lower friction level follows g(t): chunks continued from the previous final state
    (the library's friction_drift, added to the composition, interpolates g across each chunk)."""
    duration, dt, alpha0, g, chunk_s = o.duration, o.dt, o.alpha0, o.level_profile, o.level_chunk_s
    if comp.has_delay or comp.n_states or "friction_drift" in comp.names:
        raise InputError(
            "level_profile cannot be combined with friction_drift or effects with a delay or a state "
            "(they act from a run's start)"
        )
    chunk_comp, _ = compose(list(comp.effects) + ["friction_drift"])
    if abs(float(g(0.0)) - 1.0) > 1e-9:
        raise InputError("level_profile must satisfy g(0) = 1")
    fs = 1.0 / (rec * dt)
    n_chunk = max(1, int(round(chunk_s * fs)))  # samples per chunk
    n_total = int(round(duration * fs))
    blocks, x0, k0 = [], None, 0
    while k0 < n_total:
        k1 = min(k0 + n_chunk, n_total)
        t0, t1 = k0 / fs, k1 / fs
        g0, g1 = float(g(t0)), float(g(t1))
        if g0 <= 0 or g1 <= 0:
            raise InputError(f"level_profile must stay positive (g({t0:g}) = {g0:g}, g({t1:g}) = {g1:g})")
        pc = p.replace(**{n: getattr(p, n) * g0 for n in _LOWER_LEVEL})
        drift = (g1 / g0 - 1.0) / (t1 - t0)
        sel = (t >= t0 - 1e-12) & (t <= t1 + 1.0 / fs + 1e-12)
        tr = simulate_batch(
            config,
            (t[sel] - t0, uu[sel]),
            t1 - t0,
            dt=dt,
            params=pc,
            alpha0=alpha0,
            x0=x0,
            method="dp5",
            record_every=rec,
            effects=chunk_comp,
            effect_params={**values, "drift": drift},
            n_batch=1,
        )[0]
        data = tr.data.copy()
        data[:, 0] += t0
        blocks.append(data if not blocks else data[1:])
        x0 = tr.final_state
        k0 = k1
    return replace(tr, params=p, data=np.concatenate(blocks), composition=comp, effect_values=dict(values))
