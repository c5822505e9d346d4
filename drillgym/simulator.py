"""The simulator's Python interface: one call, one or many runs, any composition of effects.

>>> from drillgym import simulate
>>> traj = simulate("torsional", u=1.0, duration=30.0)          # stick-slip at 1 V
>>> traj.omega_l.max(), traj.stick_l.mean()

>>> from drillgym import simulate_batch
>>> batch = simulate_batch("coupled", u=[3.4, 3.7], duration=120.0)  # two voltages at once
>>> batch[1].omega_l[-1]

>>> traj = simulate("torsional", u=1.0, duration=30.0, effects=["motor_lag", "input_delay"],
...                 effect_params={"tau_m": 0.03, "delay": 0.02})
>>> traj.u_m                                                      # the lag's state is recorded

Everything runs through the compiled kernels of the composition of effects
(:mod:`drillgym.effects`; the base model is the empty composition). The parts:

* :mod:`drillgym.run_setup` - the arrays a run starts from (commands, states, delay lines);
* :mod:`drillgym.lane_runner` - the SIMD lane kernel over a batch, in whole blocks of lanes;
* :mod:`drillgym.trajectory` - :class:`Trajectory` and :class:`BatchTrajectory`, the results;
* :mod:`drillgym.batch_simulator` - :class:`BatchSimulator`, the stepping interface the
  environments, controllers and the rig emulator use (state kept between calls).

This module keeps their public names importable from ``drillgym.simulator``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .batch_simulator import BatchSimulator
from .configurations import Configuration, parse_configuration
from .effects.composition import compose
from .errors import InputError, InputTypeError, SimulationError
from .integrators import ADAPTIVE, DEFAULT_ATOL, DEFAULT_DT, DEFAULT_RTOL, tableau
from .lane_runner import LANE_BLOCK, LANES_MIN_BATCH, block_width, lane_chunks, pad_lanes, run_lanes
from .model import model_arguments
from .params import N_PARAMS, RigParams
from .run_setup import (
    DEFAULT_SMOOTH_EPS,
    InputLike,
    ParamsLike,
    as_voltages,
    delay_lines,
    friction_eps,
    initial_state,
    initial_states,
    input_matrix,
    optional_args,
    real_number,
    record_columns,
    step_grid,
    whole_number,
)
from .trajectory import BatchTrajectory, Trajectory, check_run

__all__ = [
    "simulate",
    "simulate_batch",
    "Trajectory",
    "BatchTrajectory",
    "BatchSimulator",
    "initial_state",
    "InputLike",
    "ParamsLike",
    "LANE_BLOCK",
    "LANES_MIN_BATCH",
    "DEFAULT_SMOOTH_EPS",
    "block_width",
    "lane_chunks",
    "pad_lanes",
    "run_lanes",
]

_input_matrix = input_matrix  # the name the integrator tests import


def _batch_size(n_batch, x0, alpha0, params, u, n_steps: int) -> int:
    """The number of runs B that the arguments of :func:`simulate_batch` ask for (at least 1)."""
    sizes = [0 if n_batch is None else whole_number("n_batch", n_batch, 1)]
    if x0 is not None and np.ndim(x0) == 2:
        sizes.append(np.shape(x0)[0])
    if np.ndim(alpha0) == 1:
        sizes.append(len(alpha0))
    if isinstance(params, np.ndarray) and params.ndim == 2:
        sizes.append(params.shape[0])
    elif params is not None and not isinstance(params, (RigParams, np.ndarray)):
        sizes.append(len(params))
    if not callable(u) and not isinstance(u, tuple):
        ua = np.asarray(u)
        if ua.ndim == 2:
            sizes.append(ua.shape[0])
        elif ua.ndim == 1 and ua.shape[0] != n_steps:
            sizes.append(ua.shape[0])
    return max(max(sizes), 1)


def simulate_batch(
    config: str | Configuration,
    u: InputLike,
    duration: float,
    *,
    dt: float = DEFAULT_DT,
    params: ParamsLike = None,
    x0: np.ndarray | None = None,
    alpha0: float | Sequence[float] = 0.0,
    n_batch: int | None = None,
    method: str = "rk4",
    record_every: int = 1,
    friction: str = "exact",
    smooth_eps: float = DEFAULT_SMOOTH_EPS,
    parallel: bool = False,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
    t0: float | Sequence[float] = 0.0,
    u_before: np.ndarray | None = None,
    record: Sequence[str] | None = None,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    model: Any = None,
) -> BatchTrajectory:
    """Simulate B runs in one compiled call.

    Parameters
    ----------
    config : str or Configuration
        ``"upper"``, ``"torsional"``, ``"lateral"``, ``"coupled"`` or ``"free_vibration"``.
    u : float, array_like, tuple or callable
        Motor voltage command (V): a scalar, one value per run ``(B,)``, per-step values ``(n,)``
        or ``(B, n)``, a ``(t, u)`` pair of arrays (zero-order hold), or a function of time.
        ``|u| <= 50 V`` as on the command line and in recordings (the +-5 V amplifier limit
        belongs to the environments and the rig).
    duration : float
        Simulated time (s).
    dt : float, optional
        Fixed step (s). Default 1 ms.
    params : RigParams, list of RigParams or numpy.ndarray, optional
        Parameters of all runs, one per run, or a ``(B, n_params)`` matrix (base parameters, or
        base then effect parameters in the composition's layout).
    x0 : numpy.ndarray, optional
        Initial states ``(n_state,)`` or ``(B, n_state)`` (mechanical states, optionally followed
        by the effects' states); default rest with winding ``alpha0``.
    alpha0 : float or sequence of float, optional
        Initial winding ``theta_l - theta_u`` (rad), scalar or per run.
    n_batch : int, optional
        Number of runs when the other arguments do not give it.
    method : str, optional
        ``"rk4"`` (default) or ``"dp5"`` (fixed step ``dt``), or ``"dp45"``: adaptive
        Dormand-Prince 5(4) steps between the located events (tolerances ``rtol``, ``atol`` per
        state), outputs interpolated on the grid of ``dt``; several times faster for one long run
        (``benchmarks/bench_single_vs_scipy.py``).
    record_every : int, optional
        Keep every k-th step. Default 1.
    friction : str, optional
        ``"exact"`` (set-valued, event-driven; default) or ``"smooth"`` (``tanh(w / smooth_eps)``).
    smooth_eps : float, optional
        Speed scale of the smooth friction law (rad/s).
    parallel : bool, optional
        Spread the batch over all cores (threads).
    effects : optional
        Effects added to the base model: names, ``"path/to/file.py:NAME"``, Effect classes or
        instances (``MotorLag(tau_m=0.02)``), or a Composition (see :mod:`drillgym.effects`).
    effect_params : mapping of str to float, optional
        Values of the effects' parameters by name (defaults: each Parameter's).
    t0 : float or sequence of float, optional
        Start time (s), scalar or per run: time-dependent effects see ``t0`` plus the elapsed
        time (e.g. a segment of a recording restarted in the middle); the outputs' ``t`` starts
        there.
    u_before : numpy.ndarray, optional
        Commands (V) of the steps before the start, ``(m,)`` or ``(B, m)``, oldest first: they fill
        the delay lines of Delay effects (default: the first command held before the start).
    record : sequence of str, optional
        The columns to keep (names of ``output_names``, e.g. ``("t", "omega_l")``); default all.
        Recording costs what it records: 256 runs of 60 s at every step and all 18 columns take
        2.2 GB, ``record=("omega_l",), record_every=10`` takes 12 MB.
    rtol, atol : float, optional
        Relative and absolute tolerances of ``"dp45"``.
    model : Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file) all runs share: its base parameters,
        effects and values (an effect that does not act in ``config`` left out, with a warning); refused beside
        ``params``, ``effects`` or ``effect_params``.

    Returns
    -------
    BatchTrajectory
        The recorded samples of every run.

    Raises
    ------
    InputError
        An argument cannot be used (the message names it and what is valid).
    SimulationError
        A run diverged (NaN or infinite state).
    """
    cfg = parse_configuration(config)
    params, effects, effect_params = model_arguments(
        model, params, effects, effect_params, "simulate_batch()", cfg.label
    )  # a model's effect that does not act in cfg is left out with a warning
    comp, values = compose(effects, effect_params)
    duration, dt = step_grid(duration, dt)
    record_every = whole_number("record_every", record_every, 1)
    n_steps = int(round(duration / dt))
    B = _batch_size(n_batch, x0, alpha0, params, u, n_steps)
    P = comp.matrix(params, B, values)
    U, USTEP = input_matrix(u, B, n_steps, dt)
    Y = initial_states(comp, B, x0, alpha0)
    if cfg.lateral_free is False:
        Y[:, 4:8] = 0.0
    MODE = np.zeros((B, 2), dtype=np.int64)
    n_rec = n_steps // record_every + 1
    names, COLS = record_columns(comp, record)
    A, b, c = tableau(method)
    eps = friction_eps(friction, smooth_eps)
    HIST, HEAD = delay_lines(comp, P, dt, u_before)
    T0 = np.ascontiguousarray(np.broadcast_to(np.asarray(t0, dtype=np.float64), (B,)))
    if not np.all(np.isfinite(T0)):
        raise InputError(f"t0 must be finite, got {t0!r}")
    k = comp.kernels
    adaptive = method.lower() in ADAPTIVE
    if adaptive and not (rtol > 0 and atol > 0):
        raise InputError(f"rtol and atol must be > 0, got {rtol!r}, {atol!r}")
    lanes = not adaptive and B >= LANES_MIN_BATCH and eps == 0.0
    # the lane kernel stores a sample's column over the lanes contiguously: sample-major storage,
    # seen through data (B, n_samples, n_columns) as a transposed view; the scalar paths store run by run
    OUT = np.empty((n_rec, len(names), B)).transpose(2, 0, 1) if lanes else np.empty((B, n_rec, len(names)))
    with arithmetic_failure_is_divergence(comp.label):
        if adaptive:
            args = (
                Y,
                MODE,
                U,
                P,
                int(cfg),
                float(dt),
                T0,
                eps,
                A,
                b,
                c,
                int(record_every),
                OUT,
                True,
                n_steps,
                HIST,
                HEAD,
                float(rtol),
                float(atol),
            )
            k.adaptive.run_batch_adaptive(*args, *optional_args(COLS, USTEP, OUT.shape[2]))
        elif lanes:
            run_lanes(
                k.lanes.lanes_run,
                Y,
                MODE,
                U,
                P,
                int(cfg),
                float(dt),
                int(record_every),
                OUT.transpose(1, 2, 0),
                n_steps,
                parallel,
                HIST,
                HEAD,
                T0,
                COLS,
                USTEP,
                (A, b, c),
            )
        else:
            runner = k.stepping.run_batch_parallel if parallel else k.stepping.run_batch_serial
            args = (Y, MODE, U, P, int(cfg), float(dt), T0, eps, A, b, c, int(record_every), OUT, True, n_steps)
            runner(*args, HIST, HEAD, *optional_args(COLS, USTEP, OUT.shape[2]))
    check_run(OUT, names, Y, comp.full_state_names, P, T0, float(dt), int(record_every), comp.label)
    keep = B <= 64 or params is not None
    plist = [RigParams.from_vector(P[i, :N_PARAMS]) for i in range(B)] if keep else [RigParams()] * B
    vlist = [comp.split(P[i])[1] for i in range(B)] if keep else [dict(values)] * B
    return BatchTrajectory(cfg, plist, float(dt), method, OUT, comp, vlist, names if record is not None else None)


@contextlib.contextmanager
def arithmetic_failure_is_divergence(model: str):
    """Within the block, a division by zero or an overflow of the compiled model is a :class:`SimulationError`.

    The kernels stop at the first such failure (the state has left every physical range: a
    speed that overflows the brake law, a zero mass of the lateral model); the user gets one line
    naming the model instead of numba's traceback.
    """
    try:
        yield
    except (ZeroDivisionError, OverflowError, FloatingPointError) as exc:
        raise SimulationError(
            f"the run diverged: the compiled model {model!r} failed ({type(exc).__name__}: {exc}) with the "
            f"parameters and initial state given; check the parameters, x0, alpha0 and the effects' values"
        ) from None


def check_one_run(config: Any, duration: Any, dt: Any, record_every: Any, effects: Any, effect_params: Any) -> None:
    """Refuse, as ``drillgym simulate`` does, a step that does not divide the duration, a recording
    interval that does not divide the steps and an effect that does not act in the configuration
    (each would change the run or its record without a word).

    Raises
    ------
    InputError
        ``dt`` does not divide ``duration`` (the run would end early or late), or ``record_every``
        does not divide the steps (the run's end would not be recorded).
    EffectError
        An effect does not act in ``config``.
    """
    cfg = parse_configuration(config)
    duration, dt = real_number("duration", duration, "s"), real_number("dt", dt, "s")
    if np.isfinite(duration) and np.isfinite(dt) and 0 < dt <= 0.1 and duration > 0:
        steps = duration / dt
        if abs(steps - round(steps)) > 1e-6 * max(1.0, steps) or round(steps) < 1:
            raise InputError(
                f"dt = {dt:g} s does not divide duration = {duration:g} s ({steps:g} steps): the run would end "
                f"at {max(round(steps), 1) * dt:g} s; choose a step that divides the duration"
            )
        every = whole_number("record_every", record_every, 1)
        if round(steps) % every:
            raise InputError(
                f"record_every = {every} does not divide the run's {round(steps)} steps: its end "
                f"({duration:g} s) would not be recorded; choose a divisor of {round(steps)}"
            )
    comp, _ = compose(effects, effect_params)
    comp.refuse_not_acting(cfg.label)


def simulate(
    config: str | Configuration,
    u: InputLike,
    duration: float,
    *,
    dt: float = DEFAULT_DT,
    params: RigParams | None = None,
    x0: np.ndarray | None = None,
    alpha0: float = 0.0,
    method: str = "rk4",
    record_every: int = 1,
    friction: str = "exact",
    smooth_eps: float = DEFAULT_SMOOTH_EPS,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
    record: Sequence[str] | None = None,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    model: Any = None,
) -> Trajectory:
    """Simulate one run of the rig.

    Parameters
    ----------
    config : str or Configuration
        ``"upper"``, ``"torsional"``, ``"lateral"``, ``"coupled"`` or ``"free_vibration"``.
    u : float, array_like, tuple or callable
        Motor voltage (V): a constant, per-step values ``(n,)``, a ``(t, u)`` table or a function
        of time.
    duration : float
        Simulated time (s).
    dt : float, optional
        Fixed step (s). Default 1 ms.
    params : RigParams or numpy.ndarray, optional
        The parameters (or one parameter vector); default the nominal ones.
    x0 : numpy.ndarray, optional
        Initial state ``(n_state,)``; default rest with winding ``alpha0``.
    alpha0 : float, optional
        Initial winding (rad).
    method : str, optional
        ``"rk4"``, ``"dp5"`` or ``"dp45"`` (see :func:`simulate_batch`).
    record_every : int, optional
        Keep every k-th step.
    friction : str, optional
        ``"exact"`` (default) or ``"smooth"``.
    smooth_eps : float, optional
        Speed scale of the smooth friction law (rad/s).
    effects : optional
        Effects added to the base model (see :func:`simulate_batch`).
    effect_params : mapping of str to float, optional
        Values of the effects' parameters by name.
    record : sequence of str, optional
        The columns to keep; default all.
    rtol, atol : float, optional
        Tolerances of ``"dp45"``.
    model : Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file): its base parameters, effects and
        values (an effect that does not act in ``config`` left out, with a warning); refused beside ``params``,
        ``effects`` or ``effect_params``.

    Returns
    -------
    Trajectory
        The recorded outputs, one row per sample.

    Raises
    ------
    InputTypeError
        ``params`` is neither one RigParams nor one parameter vector.
    InputError
        Several initial states or input sequences, or an argument :func:`simulate_batch` refuses.
    SimulationError
        The run diverged.
    """
    params, effects, effect_params = model_arguments(
        model, params, effects, effect_params, "simulate()", parse_configuration(config).label
    )
    if params is not None and not isinstance(params, RigParams):
        if not (isinstance(params, np.ndarray) and params.ndim == 1):
            raise InputTypeError(
                "simulate() takes one RigParams (or one parameter vector); use simulate_batch for several"
            )
        params = params[None, :]
    if x0 is not None and np.ndim(x0) != 1:
        raise InputError("simulate() takes one initial state")
    if np.ndim(alpha0) != 0:
        raise InputError("simulate() takes one initial winding alpha0; use simulate_batch for several")
    check_one_run(config, duration, dt, record_every, effects, effect_params)
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) > 1:
        raise InputError("simulate() takes a scalar or one input sequence; use simulate_batch for several")
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) == 1:
        u = as_voltages(u)[None, :]  # one per-step sequence
    batch = simulate_batch(
        config,
        u,
        duration,
        dt=dt,
        params=params,
        x0=x0,
        alpha0=alpha0,
        n_batch=1,
        method=method,
        record_every=record_every,
        friction=friction,
        smooth_eps=smooth_eps,
        effects=effects,
        effect_params=effect_params,
        record=record,
        rtol=rtol,
        atol=atol,
    )
    return batch[0]
