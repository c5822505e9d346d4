"""The simulator's Python interface: one call, one or many trajectories, any composition of effects.

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
(:mod:`drillgym.effects`; the base model is the empty composition);
``BatchSimulator`` is the stepping interface the environments, controllers and
the rig emulator use (state kept between calls).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence, Union

import numpy as np

from .configurations import N_STATE, STATE_NAMES, Configuration, parse_configuration
from .effects.composition import Composition, compose
from .integrators import ADAPTIVE, DEFAULT_ATOL, DEFAULT_DT, DEFAULT_RTOL, OUTPUT_NAMES, tableau
from .params import N_PARAMS, RigParams

__all__ = ["simulate", "simulate_batch", "Trajectory", "BatchTrajectory", "BatchSimulator", "initial_state",
           "InputLike", "ParamsLike"]

InputLike = Union[float, Sequence[float], np.ndarray, tuple, Callable[[np.ndarray], np.ndarray]]
ParamsLike = Union[RigParams, Sequence[RigParams], np.ndarray, None]
DEFAULT_SMOOTH_EPS = 1e-3  # rad/s, for friction="smooth"
LANES_MIN_BATCH = 8  # batches at least this large use the SIMD lane kernel (fixed-step tableau, exact friction)
#: lanes per iteration of the lane kernel's widest vectorised loop (LLVM unrolls some loops to four vectors
#: of 8 doubles with AVX-512).  Lanes past a loop's last whole iteration run its remainder loop: 2.5 times
#: slower per lane when scalar, and rounded differently (a lane's last bits then depended on the batch
#: size and the number of cores; 16-lane blocks still did).  :func:`run_lanes` pads every chunk to whole blocks.
LANE_BLOCK = 32


def initial_state(alpha0: float = 0.0, theta_u0: float = 0.0, omega_u0: float = 0.0, omega_l0: float = 0.0,
                  x0: float = 0.0, y0: float = 0.0, vx0: float = 0.0, vy0: float = 0.0) -> np.ndarray:
    """A mechanical state vector (see :mod:`drillgym.configurations`); alpha0 = initial winding
    theta_l - theta_u (rad).  Effect states, when a composition has any, start at 0."""
    return np.array([theta_u0, theta_u0 + alpha0, omega_u0, omega_l0, x0, y0, vx0, vy0], dtype=np.float64)


def _table_steps(ts: np.ndarray, n_steps: int, dt: float) -> np.ndarray:
    """First grid step of each entry of a (t, u) table: step i uses the last entry with
    ts[j] <= t_i (+1e-12 dt), t_i = i dt (the first entry before its time)."""
    first = np.maximum(np.ceil(ts / dt - 1e-12), 0).astype(np.int64)
    for j, tj in enumerate(ts):  # the grid's own rounding decides, as a comparison against t_i would
        while first[j] > 0 and (first[j] - 1) * dt + 1e-12 * dt >= tj:
            first[j] -= 1
        while first[j] * dt + 1e-12 * dt < tj:
            first[j] += 1
    first[0] = 0
    return first


def _input_matrix(u: InputLike, n_batch: int, n_steps: int, dt: float) -> tuple[np.ndarray, np.ndarray | None]:
    """(U, USTEP): per-step commands (B, n_steps), zero-order hold: step i uses u(t_i); a constant command
    (scalar or one per trajectory) stays one column (B, 1), never expanded over the steps; a (t, u)
    table stays its m entries (B, m) with USTEP (m,) the step from which each applies (evaluated in
    the kernels)."""
    steps = None
    if callable(u):
        U = np.asarray(u(np.arange(n_steps) * dt), dtype=np.float64)
    elif isinstance(u, tuple) and len(u) == 2:
        ts, us = (np.asarray(a, dtype=np.float64) for a in u)
        if ts.ndim != 1 or ts.size == 0 or us.shape[-1] != ts.size or us.ndim > 2:
            raise ValueError(f"a (t, u) input needs t (m,) and u (m,) or (B, m); got {ts.shape} and {us.shape}")
        if not (np.all(np.isfinite(ts)) and np.all(np.diff(ts) >= 0)):
            raise ValueError("the times of a (t, u) input must be finite and non-decreasing")
        steps = _table_steps(ts, n_steps, dt)
        U = us
    else:
        U = np.asarray(u, dtype=np.float64)
        if U.ndim == 0:
            U = np.full((n_batch, 1), float(U))
        elif U.ndim == 1 and U.shape[0] == n_batch and n_steps != n_batch:
            U = U[:, None].copy()
    if U.ndim == 1:
        U = np.broadcast_to(U, (n_batch, U.shape[0]))
    if steps is None and U.shape[-1] != 1 and U.shape[-1] < n_steps:
        raise ValueError(f"input signal has {U.shape[-1]} samples, the run needs {n_steps} (one per step)")
    if steps is None and U.shape[-1] != 1:
        U = U[..., :n_steps]
    U = np.ascontiguousarray(U, dtype=np.float64)
    if U.shape[0] != n_batch:
        raise ValueError(f"input has {U.shape[0]} rows for a batch of {n_batch}")
    if not np.all(np.isfinite(U)):
        bad = np.argwhere(~np.isfinite(U))[0]
        raise ValueError(f"input voltage is NaN/inf (trajectory {bad[0]}, {'entry' if steps is not None else 'step'} "
                         f"{bad[1]})")
    return U, steps


def _delay_lines(comp: Composition, P: np.ndarray, dt: float,
                 u_before: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Delay lines (B, L) and heads (B,) for the composition's Delay effects: empty (head -1: the first
    command is taken as held before the start) or filled with the commands of the steps before the
    start, ``u_before`` (B, m) oldest first (older steps than m: the oldest value held)."""
    L = comp.delay_line_length(P, dt)
    B = P.shape[0]
    H, head = np.zeros((B, L)), np.full(B, -1, dtype=np.int64)
    if u_before is not None and comp.has_delay:
        ub = np.asarray(u_before, dtype=np.float64)
        ub = np.broadcast_to(ub if ub.ndim == 2 else ub[None, :], (B, ub.shape[-1]))
        if ub.shape[1] > 0:
            if not np.all(np.isfinite(ub)):
                raise ValueError("u_before contains NaN or inf")
            m = min(ub.shape[1], L)
            H[:, L - m:] = ub[:, ub.shape[1] - m:]
            H[:, :L - m] = ub[:, ub.shape[1] - m:ub.shape[1] - m + 1]
            head[:] = L - 1
    return H, head


@dataclass
class Trajectory:
    """One simulated run: samples (rows) of the columns ``output_names``.

    Attributes named like the columns give 1-D arrays: ``t`` (s), ``u`` (V, the command),
    ``theta_u``, ``theta_l``, ``alpha`` (rad), ``omega_u``, ``omega_l`` (rad/s),
    ``x``, ``y`` (fixed frame, m), ``r`` (m), ``x_rot``, ``y_rot`` (rotating frame),
    ``Tfu``, ``Tfl`` (N m), ``stick_u``, ``stick_l`` (1 = stuck), then the effects' states
    (e.g. ``u_m``, V, with motor_lag).  ``effect_values`` holds the effects' parameters.
    """

    config: Configuration
    params: RigParams
    dt: float
    method: str
    data: np.ndarray
    composition: Composition = field(default_factory=lambda: Composition(()))
    effect_values: dict = field(default_factory=dict)
    names: tuple | None = None  # the recorded columns (default: all of the composition's output_names)

    def __getattr__(self, name: str) -> np.ndarray:
        if "data" in self.__dict__ and "composition" in self.__dict__:
            idx = _column_index(self.output_names)
            if name in idx:
                return self.data[:, idx[name]]
            if name in self.composition.output_names:
                raise AttributeError(f"column {name!r} was not recorded (record={self.output_names})")
        raise AttributeError(name)

    @property
    def output_names(self) -> tuple[str, ...]:
        return self.names if self.names is not None else self.composition.output_names

    @property
    def final_state(self) -> np.ndarray:
        """State vector at the last sample (mechanical states, then the effects' states), to continue a run."""
        names = self.composition.full_state_names
        state_cols = [n + "_rot" if n in ("x", "y", "vx", "vy") else n for n in names]  # rotating-frame columns
        idx = _column_index(self.output_names)
        missing = [c for c in state_cols if c not in idx]
        if missing:
            raise ValueError(f"final_state needs the state columns; {', '.join(missing)} were not recorded")
        row = self.data[-1]
        return np.array([row[idx[c]] for c in state_cols])

    @property
    def parameter_vector(self) -> np.ndarray:
        """The kernels' parameter vector of this run (base, then the effects' parameters)."""
        return self.composition.vector(self.params, self.effect_values)

    def columns(self) -> dict[str, np.ndarray]:
        return {n: self.data[:, i] for i, n in enumerate(self.output_names)}

    def to_csv(self, path, description: str = "") -> None:
        """Write in the interchange format of ../shared/DATA_FORMAT.md."""
        from .io import write_trajectory_csv

        write_trajectory_csv(self, path, description=description)


def _column_index(names: Sequence[str]) -> dict[str, int]:
    return {n: i for i, n in enumerate(names)}


@dataclass
class BatchTrajectory:
    """Many runs of one configuration: ``data`` has shape (B, n_samples, n_outputs)."""

    config: Configuration
    params: list[RigParams]
    dt: float
    method: str
    data: np.ndarray
    composition: Composition = field(default_factory=lambda: Composition(()))
    effect_values: list = field(default_factory=list)
    names: tuple | None = None  # the recorded columns (default: all of the composition's output_names)

    @property
    def output_names(self) -> tuple[str, ...]:
        return self.names if self.names is not None else self.composition.output_names

    def __len__(self) -> int:
        return self.data.shape[0]

    def __getitem__(self, k: int) -> Trajectory:
        vals = self.effect_values[k] if self.effect_values else {}
        return Trajectory(self.config, self.params[k], self.dt, self.method, self.data[k], self.composition, vals,
                          self.names)

    def __getattr__(self, name: str) -> np.ndarray:
        if "data" in self.__dict__ and "composition" in self.__dict__:
            idx = _column_index(self.output_names)
            if name in idx:
                return self.data[:, :, idx[name]]
            if name in self.composition.output_names:
                raise AttributeError(f"column {name!r} was not recorded (record={self.output_names})")
        raise AttributeError(name)


def _friction_eps(friction: str, smooth_eps: float) -> float:
    if friction == "exact":
        return 0.0
    if friction == "smooth":
        if not smooth_eps > 0:
            raise ValueError("smooth_eps must be > 0 for friction='smooth'")
        return float(smooth_eps)
    raise ValueError(f"friction must be 'exact' (set-valued, default) or 'smooth', got {friction!r}")


def _record_columns(comp: Composition, record: Sequence[str] | None) -> tuple[tuple, np.ndarray | None]:
    """(names, column indices for the kernels) of the recorded outputs; None = all columns."""
    if record is None:
        return comp.output_names, None
    if isinstance(record, str):
        record = (record,)
    names = tuple(record)
    unknown = [n for n in names if n not in comp.output_names]
    if unknown or len(set(names)) != len(names) or not names:
        what = f"unknown column {unknown[0]!r}" if unknown else "empty or repeated columns"
        raise ValueError(f"record: {what}; choose among {', '.join(comp.output_names)}")
    idx = _column_index(comp.output_names)
    return names, np.array([idx[n] for n in names], dtype=np.int64)


def _optional(COLS: np.ndarray | None, USTEP: np.ndarray | None, n_out: int) -> tuple:
    """The kernels' optional trailing arguments (COLS, USTEP): omitted, not None, when not used (one
    compiled version per combination actually used; a table without chosen columns records all)."""
    if USTEP is None:
        return () if COLS is None else (COLS,)
    return (np.arange(n_out, dtype=np.int64) if COLS is None else COLS, USTEP)


def block_width(n_lanes: int) -> int:
    """n_lanes rounded up to whole blocks of LANE_BLOCK lanes."""
    return -(-n_lanes // LANE_BLOCK) * LANE_BLOCK


def lane_chunks(n_lanes: int, parallel: bool) -> list[tuple[int, int, int]]:
    """(first lane, end lane, padded width) of each chunk of a lane-kernel call: whole blocks of
    LANE_BLOCK lanes, as evenly as possible over the cores (one chunk unless parallel); the last chunk's
    width is its lanes rounded up to whole blocks.  Every lane then runs the vectorised loop body, so a lane's
    result does not depend on the batch size, its place in it or the number of cores."""
    blocks = block_width(n_lanes) // LANE_BLOCK
    n_chunks = min(os.cpu_count() or 1, blocks) if parallel else 1
    per = -(-blocks // n_chunks) * LANE_BLOCK
    return [(lo, min(lo + per, n_lanes), block_width(min(lo + per, n_lanes) - lo)) for lo in range(0, n_lanes, per)]


def pad_lanes(arrays: Sequence[np.ndarray], width: int, out: "list[np.ndarray] | None" = None) -> list[np.ndarray]:
    """Each array (lanes along axis 0) in a buffer of ``width`` lanes, its last lane repeated into the rest;
    ``out``: buffers to reuse (all new when missing or one is of another shape)."""
    if out is None or any(b.shape != (width,) + a.shape[1:] for a, b in zip(arrays, out)):
        out = [np.empty((width,) + a.shape[1:], dtype=a.dtype) for a in arrays]
    for a, b in zip(arrays, out):
        n = a.shape[0]
        b[:n] = a
        b[n:] = a[n - 1]
    return out


def run_lanes(lanes_run, Y, MODE, U, P, cfg, dt, record_every, OUT, n_steps, parallel, HIST, HEAD, T0, COLS,
              USTEP, tab):
    """The SIMD lane kernel over the batch; with parallel, one chunk per core in threads (nogil).
    OUT is sample-major, (n_samples, n_columns, B); ``tab`` the fixed-step tableau (A, b, c).
    Chunks are whole blocks of LANE_BLOCK lanes (:func:`lane_chunks`): a short chunk is padded with
    copies of its last lane, run, and its real lanes copied back (Y, MODE, friction, delay lines, OUT).
    Used by :func:`simulate_batch` and the segmented simulation of the identification."""
    chunks = lane_chunks(Y.shape[0], parallel)
    FR = np.zeros((Y.shape[0], 2))

    def run(lo, hi, width):
        s = slice(lo, hi)
        if hi - lo == width:
            lanes_run(Y[s], MODE[s], U[s], P[s], cfg, dt, T0[s].copy(), record_every, OUT[:, :, s], n_steps, True,
                      FR[s], HIST[s], HEAD[s], *tab, *_optional(COLS, USTEP, OUT.shape[1]))
            return
        Yp, MODEp, Up, Pp, Tp, FRp, HISTp, HEADp = pad_lanes([a[s] for a in (Y, MODE, U, P, T0, FR, HIST, HEAD)], width)
        OUTp = np.empty(OUT.shape[:2] + (width,))
        lanes_run(Yp, MODEp, Up, Pp, cfg, dt, Tp, record_every, OUTp, n_steps, True, FRp, HISTp, HEADp, *tab,
                  *_optional(COLS, USTEP, OUT.shape[1]))
        n = hi - lo
        Y[s], MODE[s], FR[s], HIST[s], HEAD[s] = Yp[:n], MODEp[:n], FRp[:n], HISTp[:n], HEADp[:n]
        OUT[:, :, s] = OUTp[:, :, :n]

    if len(chunks) == 1:
        run(*chunks[0])
    else:
        list(_chunk_pool().map(lambda c: run(*c), chunks))


_POOL: "ThreadPoolExecutor | None" = None
_POOL_LOCK = threading.Lock()


def _chunk_pool() -> ThreadPoolExecutor:
    """The process's threads for the lane kernel's chunks (one per core), started once: a pool started per call
    cost about 1 ms of a 35 ms segmented prediction, with the GIL held.  Callers on several threads share it
    (their chunks queue; the cores are the limit either way)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix="drillgym-lanes")
        return _POOL


def _forget_pool_in_child() -> None:
    """A forked child has none of the parent's threads (its pool would never run a chunk) and maybe a lock
    another thread held at the fork: it starts both anew."""
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_in_child)


def _initial_states(comp: Composition, B: int, x0: Any, alpha0: Any) -> np.ndarray:
    """(B, n_state) initial states: at rest with winding alpha0, or x0 (all states, or the 8 mechanical
    ones).  Effect states not given start at 0, except lag states: NaN, which the kernels replace at
    the first step by the first command held before the start (as the delay lines; identification
    starts its lag filter the same way)."""
    n = comp.n_state
    if x0 is None:
        Y = np.zeros((B, n))
        Y[:, 1] = np.broadcast_to(np.asarray(alpha0, dtype=float), (B,))
        Y[:, list(comp.lag_state_columns)] = np.nan
        return Y
    X = np.asarray(x0, dtype=np.float64)
    given = X.shape[-1]
    if given == N_STATE and n > N_STATE:  # mechanical states only: effect states start at 0
        X = np.concatenate([X, np.zeros(X.shape[:-1] + (n - N_STATE,))], axis=-1)
    if X.shape[-1] != n:
        raise ValueError(f"initial state must have {n} entries ({', '.join(comp.full_state_names)}), "
                         f"got {X.shape[-1]}")
    Y = np.array(np.broadcast_to(X, (B, n)))
    if not np.all(np.isfinite(Y)):
        raise ValueError("initial state contains NaN or inf")
    if given == N_STATE:
        Y[:, list(comp.lag_state_columns)] = np.nan
    return Y


def simulate_batch(config: "str | Configuration", u: InputLike, duration: float, *, dt: float = DEFAULT_DT,
                   params: ParamsLike = None, x0: np.ndarray | None = None, alpha0: "float | Sequence[float]" = 0.0,
                   n_batch: int | None = None, method: str = "rk4", record_every: int = 1,
                   friction: str = "exact", smooth_eps: float = DEFAULT_SMOOTH_EPS,
                   parallel: bool = False, effects: Any = None,
                   effect_params: Mapping[str, float] | None = None, t0: "float | Sequence[float]" = 0.0,
                   u_before: np.ndarray | None = None, record: Sequence[str] | None = None,
                   rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> BatchTrajectory:
    """Simulate B trajectories in one compiled call.

    Args:
        config: 'upper', 'torsional', 'lateral', 'coupled' or 'free_vibration'.
        u: motor voltage command (V): a scalar, one value per trajectory (B,), per-step values (n,)
            or (B, n), a (t, u) pair of arrays (zero-order hold), or a function of time.  Any
            voltage is accepted (the +/-5 V amplifier limit belongs to the environments and the rig).
        duration: simulated time (s).
        dt: fixed step (s).  Default 1 ms.
        params: RigParams, a list of them (one per trajectory) or a (B, n_params) matrix (base
            parameters, or base then effect parameters in the composition's layout).
        x0: initial states (n_state,) or (B, n_state) (mechanical states, optionally followed by the
            effects' states); default rest with winding ``alpha0``.
        alpha0: initial winding theta_l - theta_u (rad), scalar or per trajectory.
        method: 'rk4' or 'dp5' (fixed step dt), or 'dp45': adaptive Dormand-Prince 5(4) steps between the
            located events (tolerances ``rtol``, ``atol`` per state), outputs interpolated on the grid of
            dt; several times faster for one long trajectory (benchmarks/bench_single_vs_scipy.py).
        record_every: keep every k-th step.
        record: the columns to keep (names of ``output_names``, e.g. ``("t", "omega_l")``); default all.
            Recording costs what it records: 256 trajectories x 60 s at every step and all 18 columns take
            2.2 GB, ``record=("omega_l",), record_every=10`` takes 12 MB.
        friction: 'exact' (set-valued, event-driven; default) or 'smooth' (tanh(w/smooth_eps)).
        parallel: spread the batch over all cores (numba threads).
        effects: effects added to the base model: names, 'path/to/file.py:NAME', Effect classes or
            instances (``MotorLag(tau_m=0.02)``), or a Composition (see :mod:`drillgym.effects`).
        effect_params: values of the effects' parameters by name (defaults: each Parameter's).
        t0: start time(s) (s), scalar or per trajectory: time-dependent effects see t0 + elapsed time
            (e.g. a segment of a recording restarted in the middle); outputs' t starts there.
        u_before: commands (V) of the steps before the start, (m,) or (B, m), oldest first: they fill
            the delay lines of Delay effects (default: the first command held before the start).
    """
    cfg = parse_configuration(config)
    comp, values = compose(effects, effect_params)
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    if not (np.isfinite(dt) and 0 < dt <= 0.1):
        raise ValueError(f"dt must be in (0, 0.1] s, got {dt!r}")
    if int(record_every) < 1:
        raise ValueError("record_every must be >= 1")
    n_steps = int(round(duration / dt))
    sizes = [n_batch or 0]
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
    B = max(max(sizes), 1)
    P = comp.matrix(params, B, values)
    U, USTEP = _input_matrix(u, B, n_steps, dt)
    Y = _initial_states(comp, B, x0, alpha0)
    if cfg.lateral_free is False:
        Y[:, 4:8] = 0.0
    MODE = np.zeros((B, 2), dtype=np.int64)
    n_rec = n_steps // record_every + 1
    names, COLS = _record_columns(comp, record)
    A, b, c = tableau(method)
    eps = _friction_eps(friction, smooth_eps)
    HIST, HEAD = _delay_lines(comp, P, dt, u_before)
    T0 = np.ascontiguousarray(np.broadcast_to(np.asarray(t0, dtype=np.float64), (B,)))
    if not np.all(np.isfinite(T0)):
        raise ValueError(f"t0 must be finite, got {t0!r}")
    k = comp.kernels
    adaptive = method.lower() in ADAPTIVE
    if adaptive and not (rtol > 0 and atol > 0):
        raise ValueError(f"rtol and atol must be > 0, got {rtol!r}, {atol!r}")
    lanes = not adaptive and B >= LANES_MIN_BATCH and eps == 0.0
    # the lane kernel stores a sample's column over the lanes contiguously: sample-major storage,
    # seen through data (B, n_samples, n_columns) as a transposed view; the scalar paths store lane by lane
    OUT = np.empty((n_rec, len(names), B)).transpose(2, 0, 1) if lanes else np.empty((B, n_rec, len(names)))
    if adaptive:
        args = (Y, MODE, U, P, int(cfg), float(dt), T0, eps, A, b, c, int(record_every), OUT, True, n_steps, HIST, HEAD,
                float(rtol), float(atol))
        k.stepping.run_batch_adaptive(*args, *_optional(COLS, USTEP, OUT.shape[2]))
    elif lanes:
        run_lanes(k.lanes.lanes_run, Y, MODE, U, P, int(cfg), float(dt), int(record_every), OUT.transpose(1, 2, 0),
                  n_steps, parallel, HIST, HEAD, T0, COLS, USTEP, (A, b, c))
    else:
        runner = k.stepping.run_batch_parallel if parallel else k.stepping.run_batch_serial
        args = (Y, MODE, U, P, int(cfg), float(dt), T0, eps, A, b, c, int(record_every), OUT, True, n_steps, HIST, HEAD)
        runner(*args, *_optional(COLS, USTEP, OUT.shape[2]))
    if not np.all(np.isfinite(Y)):
        bad = int(np.argwhere(~np.all(np.isfinite(Y), axis=1))[0, 0])
        raise FloatingPointError(f"trajectory {bad} diverged (NaN/inf state) with the model {comp.label!r}: "
                                 f"check the effects' formulas and parameter values")
    keep = B <= 64 or params is not None
    plist = [RigParams.from_vector(P[i, :N_PARAMS]) for i in range(B)] if keep else [RigParams()] * B
    vlist = [comp.split(P[i])[1] for i in range(B)] if keep else [dict(values)] * B
    return BatchTrajectory(cfg, plist, float(dt), method, OUT, comp, vlist, names if record is not None else None)


def simulate(config: "str | Configuration", u: InputLike, duration: float, *, dt: float = DEFAULT_DT,
             params: RigParams | None = None, x0: np.ndarray | None = None, alpha0: float = 0.0,
             method: str = "rk4", record_every: int = 1, friction: str = "exact",
             smooth_eps: float = DEFAULT_SMOOTH_EPS, effects: Any = None,
             effect_params: Mapping[str, float] | None = None, record: Sequence[str] | None = None,
             rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> Trajectory:
    """Simulate one trajectory (see :func:`simulate_batch` for the arguments)."""
    if params is not None and not isinstance(params, RigParams):
        if not (isinstance(params, np.ndarray) and params.ndim == 1):
            raise TypeError("simulate() takes one RigParams (or one parameter vector); use simulate_batch for several")
        params = params[None, :]
    if x0 is not None and np.ndim(x0) != 1:
        raise ValueError("simulate() takes one initial state")
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) > 1:
        raise ValueError("simulate() takes a scalar or one input sequence; use simulate_batch for several")
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) == 1:
        u = np.asarray(u, dtype=np.float64)[None, :]  # one per-step sequence
    batch = simulate_batch(config, u, duration, dt=dt, params=params, x0=x0, alpha0=alpha0, n_batch=1,
                           method=method, record_every=record_every, friction=friction, smooth_eps=smooth_eps,
                           effects=effects, effect_params=effect_params, record=record, rtol=rtol, atol=atol)
    return batch[0]


class BatchSimulator:
    """Stateful stepping of N trajectories (for environments, controllers, the emulator).

    >>> sim = BatchSimulator("torsional", n=256)
    >>> sim.reset(alpha0=np.zeros(256))
    >>> sim.advance(np.full(256, 2.0), n_steps=10)   # one 10 ms control period at dt = 1 ms
    >>> sim.omega_l, sim.stuck_l, sim.friction[:, 1]

    ``effects``/``effect_params`` as :func:`simulate_batch`: the same compiled composition, so a
    batch stepped here matches a single run of the same model (delays and lags included).
    """

    def __init__(self, config: "str | Configuration", n: int = 1, *, params: ParamsLike = None,
                 dt: float = DEFAULT_DT, method: str = "rk4", friction: str = "exact",
                 smooth_eps: float = DEFAULT_SMOOTH_EPS, effects: Any = None,
                 effect_params: Mapping[str, float] | None = None) -> None:
        self.config = parse_configuration(config)
        if int(n) < 1:
            raise ValueError("n must be >= 1")
        self.composition, self.effect_values = compose(effects, effect_params)
        self.kernels = self.composition.kernels
        self.n = int(n)
        self.dt = float(dt)
        self.method = method
        if method.lower() in ADAPTIVE:
            raise ValueError(f"BatchSimulator steps on a fixed grid: method 'rk4' or 'dp5', not {method!r}")
        self._tab = tableau(method)
        self._eps = _friction_eps(friction, smooth_eps)
        self.P = self.composition.matrix(params, self.n, self.effect_values)
        self.Y = _initial_states(self.composition, self.n, None, 0.0)
        self.MODE = np.zeros((self.n, 2), dtype=np.int64)
        self.T = np.zeros(self.n)
        self.FRIC = np.zeros((self.n, 2))
        self.HIST, self.HEAD = _delay_lines(self.composition, self.P, self.dt)
        # sample-major, no samples; as many lanes as the lane kernel runs (whole blocks: :meth:`_advance_lanes`)
        self._no_record = np.zeros((0, len(self.composition.output_names), block_width(self.n)))
        self._pad: list[np.ndarray] | None = None  # the lane kernel's padded buffers, reused
        self._lanes = self.n >= LANES_MIN_BATCH and self._eps == 0.0

    def set_params(self, params: ParamsLike, index: "int | np.ndarray | slice | None" = None) -> None:
        """Replace the parameters of all (index None) or some trajectories."""
        sel = slice(None) if index is None else index
        m = len(np.arange(self.n)[sel])
        self.P[sel] = self.composition.matrix(params, m, self.effect_values)
        self._resize_delay_lines()

    def _resize_delay_lines(self) -> None:
        L = self.composition.delay_line_length(self.P, self.dt)
        if L > self.HIST.shape[1]:  # longer delays: a longer line (contents kept, oldest first)
            H = np.zeros((self.n, L))
            for k in range(self.n):
                h = self.HEAD[k]
                if h >= 0:
                    old = np.roll(self.HIST[k], -(h + 1))  # oldest ... newest
                    H[k, L - old.size:] = old
                    H[k, :L - old.size] = old[0]
                    self.HEAD[k] = L - 1
            self.HIST = H

    def reset(self, index: "int | np.ndarray | slice | None" = None, *, alpha0: "float | np.ndarray" = 0.0,
              x0: np.ndarray | None = None) -> None:
        """Put (some) trajectories at rest with winding alpha0 (or at states x0), t = 0, delay lines
        empty (before the first command the motor saw it held)."""
        sel = np.arange(self.n)[slice(None) if index is None else index]
        sel = np.atleast_1d(sel)
        Y = _initial_states(self.composition, len(sel), x0, alpha0)
        if not self.config.lateral_free:
            Y[:, 4:8] = 0.0
        self.Y[sel] = Y
        self.T[sel] = 0.0
        self.HEAD[sel] = -1
        self.MODE[sel, 0] = np.sign(Y[:, 2]).astype(np.int64)
        self.MODE[sel, 1] = np.sign(Y[:, 3]).astype(np.int64)

    def advance(self, u: "float | np.ndarray", n_steps: int = 1) -> None:
        """Hold the command u (V, scalar or (n,)) for n_steps integration steps."""
        uu = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=np.float64), (self.n,)))
        if not np.all(np.isfinite(uu)):
            raise ValueError("voltage is NaN or inf")
        if self._lanes and n_steps > 0:
            self._advance_lanes(uu, int(n_steps))
            self.T += int(n_steps) * self.dt
            return
        A, b, c = self._tab
        self.kernels.stepping.advance_batch(self.Y, self.MODE, uu, self.P, int(self.config), self.dt, int(n_steps),
                                            self.T, self._eps, A, b, c, self.FRIC, self.HIST, self.HEAD)

    def _advance_lanes(self, uu: np.ndarray, n_steps: int) -> None:
        """The lane kernel on whole blocks of LANE_BLOCK lanes, as :func:`run_lanes`: the trajectories past the
        last whole block run beside copies of the last one, so every lane takes the vectorised loop bodies and a
        trajectory does not depend on how many are stepped with it."""
        n, width = self.n, self._no_record.shape[2]
        arrays = [self.Y, self.MODE, uu[:, None], self.P, self.T, self.FRIC, self.HIST, self.HEAD]
        if width != n:
            self._pad = arrays = pad_lanes(arrays, width, self._pad)
        Y, MODE, U, P, T, FRIC, HIST, HEAD = arrays
        self.kernels.lanes.lanes_run(Y, MODE, U, P, int(self.config), self.dt, T, 1, self._no_record, n_steps, False,
                                     FRIC, HIST, HEAD, *self._tab)
        if width != n:
            self.Y[:], self.MODE[:], self.FRIC[:], self.HIST[:], self.HEAD[:] = Y[:n], MODE[:n], FRIC[:n], HIST[:n], \
                HEAD[:n]

    def kernel_args(self, u: np.ndarray, n_steps: int) -> tuple:
        """Arguments of the composition's compiled ``stepping.advance_batch`` for holding ``u``
        over ``n_steps`` (for callers that fuse it into their own compiled loop, e.g. the envs)."""
        A, b, c = self._tab
        return (self.Y, self.MODE, u, self.P, int(self.config), self.dt, int(n_steps), self.T, self._eps, A, b, c,
                self.FRIC, self.HIST, self.HEAD)

    # convenient views -------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        return self.Y

    def __getattr__(self, name: str) -> np.ndarray:
        if "Y" in self.__dict__ and "composition" in self.__dict__:
            names = self.composition.full_state_names
            if name in names:
                return self.Y[:, names.index(name)]
        raise AttributeError(name)

    @property
    def alpha(self) -> np.ndarray:
        return self.Y[:, 1] - self.Y[:, 0]

    @property
    def lateral_fixed(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) of the lower disc centre in the fixed frame (m)."""
        c, s = np.cos(self.Y[:, 0]), np.sin(self.Y[:, 0])
        return self.Y[:, 4] * c - self.Y[:, 5] * s, self.Y[:, 4] * s + self.Y[:, 5] * c

    @property
    def friction(self) -> np.ndarray:
        """(n, 2) friction torques (Tfu, Tfl) in N m at the current state."""
        return self.FRIC

    @property
    def stuck_u(self) -> np.ndarray:
        return self.MODE[:, 0] == 0

    @property
    def stuck_l(self) -> np.ndarray:
        return self.MODE[:, 1] == 0
