"""Brute-force bifurcation sweeps, as the lab does them, run through a ``concurrent.futures.Executor``.

* :func:`sweep_constant` - one run per voltage, from rest (``start="rest"``) or
  from the slip equilibrium (``start="equilibrium"``, slightly perturbed), to
  steady state; statistics over the last ``window`` seconds.
* :func:`sweep_staircase` - the lab's quasi-static sweep: one run whose voltage
  steps up (or down) through the list, ``dwell`` seconds per level, each level
  starting from the state the previous one left; statistics over the end of
  each level.

Work is split into chunks (two per worker), each simulated by one
:func:`drillgym.simulate_batch` call in a worker.  ``executor`` is any
``concurrent.futures.Executor``: by default a :class:`drillgym.parallel.LocalExecutor`
over all cores; :class:`drillgym.parallel.RayExecutor` runs the chunks as Ray tasks on a
cluster (``drillgym bifurcation --ray auto``) with the same results.  A failed chunk is
raised as :class:`drillgym.parallel.TaskFailed` naming its voltages.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np

from ..equilibria import RigModel, model_or_params, slip_equilibria
from ..errors import InputError
from ..parallel import LocalExecutor, map_ordered, parallelism
from ..params import RigParams
from ..run_setup import U_LIMIT, as_voltages, real_number, step_grid
from ..simulator import simulate_batch
from .steady_state import STAT_NAMES, steady_state_stats

RECORD_EVERY = 10  # samples kept every 10 steps (10 ms at dt = 1 ms): enough for extremes and periods


@dataclass
class SweepResult:
    """Steady-state statistics of a sweep, per voltage.

    Attribute access gives a statistic per voltage: ``omega_l_min``, ``omega_l_max`` (rad/s), ``r_min``,
    ``r_max`` (m), ``period`` (s, NaN when not oscillating), ``stick_fraction`` of the lower disc.

    Parameters
    ----------
    kind : str
        ``"rest"``, ``"equilibrium"``, ``"up"`` or ``"down"``.
    u : ndarray
        Voltages (V).
    stats : ndarray
        (n, 6) statistics in the order above.
    """

    kind: str
    u: np.ndarray
    stats: np.ndarray  # (n, len(STAT_NAMES))

    def __getattr__(self, name: str) -> np.ndarray:
        if name in STAT_NAMES and "stats" in self.__dict__:
            return self.stats[:, STAT_NAMES.index(name)]
        raise AttributeError(name)

    def to_dict(self) -> dict:
        d = {"kind": self.kind, "u": self.u.tolist()}
        for i, n in enumerate(STAT_NAMES):
            d[n] = [None if not np.isfinite(v) else float(v) for v in self.stats[:, i]]
        return d


def _rig(params: RigParams | RigModel | None, model, config: str, who: str) -> RigModel:
    """The rig a sweep runs: ``model=`` without its effects that do not act in ``config`` (each left out with a
    warning), or ``params``, whose effects that do not act are refused (as ``simulate`` and ``compute_diagram``
    do: the sweep would drop them without a word)."""
    from ..configurations import parse_configuration

    label = parse_configuration(config).label
    rig = model_or_params(params, model, who, label)
    rig.comp.refuse_not_acting(label, "effects")
    return rig


def _run_constant(
    config: str, u: np.ndarray, x0: np.ndarray | None, duration: float, window: float, dt: float, params: RigModel
) -> np.ndarray:
    uin = u if len(u) > 1 else float(u[0])
    batch = simulate_batch(
        config,
        uin,
        duration,
        dt=dt,
        params=params.params,
        effects=params.comp,
        effect_params=params.values,
        x0=x0,
        n_batch=len(u),
        record_every=RECORD_EVERY,
    )
    n_win = int(round(window / (dt * RECORD_EVERY)))
    return np.stack([steady_state_stats(batch[k], n_win) for k in range(len(u))])


def _run_staircase(
    config: str, levels: np.ndarray, dwell: float, window: float, dt: float, params: RigModel
) -> np.ndarray:
    n_level = int(round(dwell / dt))
    U = np.repeat(levels, n_level)
    traj = simulate_batch(
        config,
        U,
        len(U) * dt,
        dt=dt,
        params=params.params,
        effects=params.comp,
        effect_params=params.values,
        n_batch=1,
        record_every=RECORD_EVERY,
    )[0]
    n_win = int(round(window / (dt * RECORD_EVERY)))
    n_rec = n_level // RECORD_EVERY
    return np.stack([steady_state_stats(traj, n_win, end=(i + 1) * n_rec + 1) for i in range(len(levels))])


def _executor(executor: Executor | None) -> tuple[Executor, bool]:
    if executor is not None:
        return executor, False
    return LocalExecutor(os.cpu_count() or 1), True


def _check(voltages, duration: float, window: float, dt: float) -> np.ndarray:
    """The sweep's voltages, checked with its run settings before any run starts (a worker's refusal would
    come back wrapped in the executor's error)."""
    u = as_voltages(voltages, "voltages").reshape(-1)
    if u.size == 0 or not np.all(np.isfinite(u)):
        raise InputError("sweep voltages must be a non-empty list of finite numbers (V)")
    if np.max(np.abs(u)) > U_LIMIT:
        raise InputError(f"sweep voltages must stay within ±{U_LIMIT:g} V, got {float(np.max(np.abs(u))):g} V")
    duration, dt = step_grid(duration, dt)
    window = real_number("window", window, "s")
    if not 0 < window <= duration:
        raise InputError(f"window ({window} s) must be positive and not longer than the run ({duration} s)")
    return u


def sweep_constant(
    config: str,
    voltages,
    *,
    start: str = "rest",
    duration: float = 120.0,
    window: float = 20.0,
    dt: float = 1e-3,
    params: RigParams | None = None,
    executor: Executor | None = None,
    chunk: int | None = None,
    progress: Callable[[int], None] | None = None,
    model=None,
) -> SweepResult:
    """Simulate each voltage from the same start and measure its steady state.

    Parameters
    ----------
    config : str
        Rig configuration.
    voltages : array_like
        Constant voltages (V).
    start : str, optional
        ``"rest"`` (default) or ``"equilibrium"`` (the first slip equilibrium, slightly disturbed).
    duration : float, optional
        Length of each run (s).  Default 120.
    window : float, optional
        Steady-state window at the end of each run (s).  Default 20.
    dt : float, optional
        Integration step (s).  Default 1e-3.
    params : RigParams, optional
        Base parameters; default the identified set.
    executor : concurrent.futures.Executor, optional
        Runs the chunks of voltages; default a process pool.
    chunk : int, optional
        Voltages per task; default twice as many tasks as workers.
    progress : callable, optional
        Receives the number of voltages of each chunk as it completes.
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path, read without ``trust``): its base
        parameters, effects and values; refused beside ``params``.

    Returns
    -------
    SweepResult
        Per voltage: steady-state omega_l range (rad/s), r range (m), period (s), stuck fraction.
    """
    u = _check(voltages, duration, window, dt)
    params = _rig(params, model, config, "sweep_constant()")
    if start == "rest":
        x0 = None
    elif start == "equilibrium":
        x0 = np.zeros((len(u), params.comp.n_state))
        for k, v in enumerate(u):
            eqs = slip_equilibria(config, v, params) if v != 0 else []
            if eqs:
                x0[k] = eqs[0].state
                x0[k, 3] *= 1.001  # a small disturbance, as on the rig
    else:
        raise InputError(f"start must be 'rest' or 'equilibrium', got {start!r}")
    ex, own = _executor(executor)
    n_chunks = max(1, min(len(u), parallelism(ex) * 2)) if chunk is None else max(1, -(-len(u) // chunk))
    parts = [idx for idx in np.array_split(np.arange(len(u)), n_chunks) if len(idx)]
    try:
        tasks = [(str(config), u[idx], None if x0 is None else x0[idx], duration, window, dt, params) for idx in parts]
        stats = np.concatenate(map_ordered(ex, _run_constant, tasks, progress=progress, sizes=[len(i) for i in parts]))
    finally:
        if own:
            ex.shutdown()
    return SweepResult(start, u, stats)


def sweep_staircase(
    config: str,
    voltages,
    *,
    dwell: float = 40.0,
    window: float = 15.0,
    dt: float = 1e-3,
    params: RigParams | None = None,
    executor: Executor | None = None,
    progress: Callable[[int], None] | None = None,
    model=None,
) -> tuple[SweepResult, SweepResult]:
    """The quasi-static lab sweep up through ``voltages`` and back down (two runs in parallel).

    Parameters
    ----------
    config : str
        Rig configuration.
    voltages : array_like
        Voltage levels (V), in increasing order.
    dwell : float, optional
        Time at each level (s).  Default 40.
    window : float, optional
        Steady-state window at the end of each level (s).  Default 15.
    dt : float, optional
        Integration step (s).  Default 1e-3.
    params : RigParams, optional
        Base parameters; default the identified set.
    executor : concurrent.futures.Executor, optional
        Runs the two sweeps; default a process pool.
    progress : callable, optional
        Receives the number of levels of each run as it completes.
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path, read without ``trust``): its base
        parameters, effects and values; refused beside ``params``.

    Returns
    -------
    up, down : SweepResult
        The sweep up and the sweep down.
    """
    u = np.sort(_check(voltages, dwell, window, dt))
    params = _rig(params, model, config, "sweep_staircase()")
    ex, own = _executor(executor)
    try:
        tasks = [(str(config), u, dwell, window, dt, params), (str(config), u[::-1].copy(), dwell, window, dt, params)]
        up, down = map_ordered(ex, _run_staircase, tasks, progress=progress, sizes=[len(u), len(u)])
        res = SweepResult("up", u, up), SweepResult("down", u[::-1].copy(), down)
    finally:
        if own:
            ex.shutdown()
    return res
