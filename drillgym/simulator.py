"""The simulator's Python interface: one call, one or many trajectories.

>>> from drillgym import simulate
>>> traj = simulate("torsional", u=1.0, duration=30.0)          # stick-slip at 1 V
>>> traj.omega_l.max(), traj.stick_l.mean()

>>> from drillgym import simulate_batch
>>> batch = simulate_batch("coupled", u=[3.4, 3.7], duration=120.0)  # two voltages at once
>>> batch[1].omega_l[-1]

Everything runs through the compiled kernels of :mod:`drillgym.integrators`;
``BatchSimulator`` is the stepping interface the environments, controllers and
the rig emulator use (state kept between calls).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Callable, Sequence, Union

import numpy as np

from .configurations import N_STATE, STATE_NAMES, Configuration, parse_configuration
from .integrators import (
    DEFAULT_DT,
    N_OUT,
    OUTPUT_NAMES,
    advance_batch,
    run_batch_parallel,
    run_batch_serial,
    tableau,
)
from .lanes import lanes_eligible, lanes_run
from .params import N_PARAMS, IDX, RigParams

__all__ = ["simulate", "simulate_batch", "Trajectory", "BatchTrajectory", "BatchSimulator", "initial_state",
           "InputLike", "ParamsLike"]

InputLike = Union[float, Sequence[float], np.ndarray, tuple, Callable[[np.ndarray], np.ndarray]]
ParamsLike = Union[RigParams, Sequence[RigParams], np.ndarray, None]
DEFAULT_SMOOTH_EPS = 1e-3  # rad/s, for friction="smooth"
LANES_MIN_BATCH = 8  # batches at least this large use the SIMD lane kernel where it applies


def initial_state(alpha0: float = 0.0, theta_u0: float = 0.0, omega_u0: float = 0.0, omega_l0: float = 0.0,
                  x0: float = 0.0, y0: float = 0.0, vx0: float = 0.0, vy0: float = 0.0, u_m0: float = 0.0) -> np.ndarray:
    """A state vector (see :mod:`drillgym.configurations`); alpha0 = initial winding theta_l - theta_u (rad)."""
    return np.array([theta_u0, theta_u0 + alpha0, omega_u0, omega_l0, x0, y0, vx0, vy0, u_m0], dtype=np.float64)


def _params_matrix(params: ParamsLike, n: int) -> np.ndarray:
    if params is None:
        params = RigParams()
    if isinstance(params, RigParams):
        return np.tile(params.to_vector(), (n, 1))
    if isinstance(params, np.ndarray) and params.dtype != object:
        P = np.atleast_2d(np.asarray(params, dtype=np.float64))
        if P.shape[1] != N_PARAMS:
            raise ValueError(f"parameter matrix must have {N_PARAMS} columns, got {P.shape[1]}")
        if P.shape[0] == 1:
            P = np.repeat(P, n, axis=0)
        if not np.all(np.isfinite(P)):
            raise ValueError("parameter matrix contains NaN or inf")
        return np.ascontiguousarray(P)
    plist = list(params)
    if len(plist) == 1:
        plist = plist * n
    if not all(isinstance(q, RigParams) for q in plist):
        raise TypeError("params must be RigParams, a sequence of RigParams or a (B, n_params) array")
    return np.stack([q.to_vector() for q in plist])


def _input_matrix(u: InputLike, n_batch: int, n_steps: int, dt: float) -> np.ndarray:
    """Per-step inputs (B, n_steps), zero-order hold: step i uses u(t_i)."""
    t = np.arange(n_steps) * dt
    if callable(u):
        U = np.asarray(u(t), dtype=np.float64)
    elif isinstance(u, tuple) and len(u) == 2:
        ts, us = (np.asarray(a, dtype=np.float64) for a in u)
        idx = np.clip(np.searchsorted(ts, t + 1e-12 * dt, side="right") - 1, 0, len(ts) - 1)
        U = us[..., idx]
    else:
        U = np.asarray(u, dtype=np.float64)
        if U.ndim == 0:
            U = np.full(n_steps, float(U))
        elif U.ndim == 1 and U.shape[0] == n_batch and n_steps != n_batch:
            U = np.repeat(U[:, None], n_steps, axis=1)
    if U.ndim == 1:
        U = np.broadcast_to(U, (n_batch, U.shape[0]))
    if U.shape[-1] < n_steps:
        raise ValueError(f"input signal has {U.shape[-1]} samples, the run needs {n_steps} (one per step)")
    U = np.ascontiguousarray(U[..., :n_steps], dtype=np.float64)
    if U.shape[0] != n_batch:
        raise ValueError(f"input has {U.shape[0]} rows for a batch of {n_batch}")
    if not np.all(np.isfinite(U)):
        bad = np.argwhere(~np.isfinite(U))[0]
        raise ValueError(f"input voltage is NaN/inf (trajectory {bad[0]}, step {bad[1]})")
    return U


def _apply_input_delay(U: np.ndarray, P: np.ndarray, dt: float) -> np.ndarray:
    """input_delay effect: u(t - delay), holding the first value before the start."""
    delays = P[:, IDX.delay]
    if not np.any(delays > 0):
        return U
    U = U.copy()
    n = U.shape[1]
    t = np.arange(n) * dt
    for k in np.flatnonzero(delays > 0):
        U[k] = np.interp(t - delays[k], t, U[k])
    return U


@dataclass
class Trajectory:
    """One simulated run: samples (rows) of the columns ``OUTPUT_NAMES``.

    Attributes named like the columns give 1-D arrays: ``t`` (s), ``u`` (V),
    ``theta_u``, ``theta_l``, ``alpha`` (rad), ``omega_u``, ``omega_l`` (rad/s),
    ``x``, ``y`` (fixed frame, m), ``r`` (m), ``x_rot``, ``y_rot`` (rotating frame),
    ``Tfu``, ``Tfl`` (N m), ``stick_u``, ``stick_l`` (1 = stuck), ``u_m`` (V).
    """

    config: Configuration
    params: RigParams
    dt: float
    method: str
    data: np.ndarray

    def __getattr__(self, name: str) -> np.ndarray:
        if name in _COLUMN and "data" in self.__dict__:
            return self.data[:, _COLUMN[name]]
        raise AttributeError(name)

    @property
    def final_state(self) -> np.ndarray:
        """State vector at the last sample (to continue a run)."""
        return self.data[-1, 2:2 + N_STATE].copy()

    def columns(self) -> dict[str, np.ndarray]:
        return {n: self.data[:, i] for i, n in enumerate(OUTPUT_NAMES)}

    def to_csv(self, path, description: str = "") -> None:
        """Write in the interchange format of ../shared/DATA_FORMAT.md."""
        from .io import write_trajectory_csv

        write_trajectory_csv(self, path, description=description)


_COLUMN = {n: i for i, n in enumerate(OUTPUT_NAMES)}


@dataclass
class BatchTrajectory:
    """Many runs of one configuration: ``data`` has shape (B, n_samples, N_OUT)."""

    config: Configuration
    params: list[RigParams]
    dt: float
    method: str
    data: np.ndarray

    def __len__(self) -> int:
        return self.data.shape[0]

    def __getitem__(self, k: int) -> Trajectory:
        return Trajectory(self.config, self.params[k], self.dt, self.method, self.data[k])

    def __getattr__(self, name: str) -> np.ndarray:
        if name in _COLUMN and "data" in self.__dict__:
            return self.data[:, :, _COLUMN[name]]
        raise AttributeError(name)


def _friction_eps(friction: str, smooth_eps: float) -> float:
    if friction == "exact":
        return 0.0
    if friction == "smooth":
        if not smooth_eps > 0:
            raise ValueError("smooth_eps must be > 0 for friction='smooth'")
        return float(smooth_eps)
    raise ValueError(f"friction must be 'exact' (set-valued, default) or 'smooth', got {friction!r}")


def _run_lanes(Y, MODE, U, P, cfg, dt, record_every, OUT, n_steps, parallel):
    """The SIMD lane kernel over the batch; with parallel, one chunk per core in threads (nogil)."""
    n_chunks = min(os.cpu_count() or 1, max(1, Y.shape[0] // LANES_MIN_BATCH)) if parallel else 1
    bounds = np.linspace(0, Y.shape[0], n_chunks + 1).astype(int)
    FR = np.zeros((Y.shape[0], 2))

    def run(i):
        s = slice(bounds[i], bounds[i + 1])
        lanes_run(Y[s], MODE[s], U[s], P[s], cfg, dt, np.zeros(bounds[i + 1] - bounds[i]), record_every, OUT[s],
                  n_steps, True, FR[s])

    if n_chunks == 1:
        run(0)
    else:
        with ThreadPoolExecutor(n_chunks) as pool:
            list(pool.map(run, range(n_chunks)))


def simulate_batch(config: "str | Configuration", u: InputLike, duration: float, *, dt: float = DEFAULT_DT,
                   params: ParamsLike = None, x0: np.ndarray | None = None, alpha0: "float | Sequence[float]" = 0.0,
                   n_batch: int | None = None, method: str = "rk4", record_every: int = 1,
                   friction: str = "exact", smooth_eps: float = DEFAULT_SMOOTH_EPS,
                   parallel: bool = False) -> BatchTrajectory:
    """Simulate B trajectories in one compiled call.

    Args:
        config: 'upper', 'torsional', 'lateral', 'coupled' or 'free_vibration'.
        u: motor voltage (V): a scalar, one value per trajectory (B,), per-step values (n,) or (B, n),
            a (t, u) pair of arrays (zero-order hold), or a function of time.  Any voltage is
            accepted (the +/-5 V amplifier limit belongs to the environments and the rig).
        duration: simulated time (s).
        dt: fixed step (s).  Default 1 ms.
        params: RigParams, a list of them (one per trajectory) or a (B, n_params) matrix.
        x0: initial states (N_STATE,) or (B, N_STATE); default rest with winding ``alpha0``.
        alpha0: initial winding theta_l - theta_u (rad), scalar or per trajectory.
        method: 'rk4' or 'dp5'.
        record_every: keep every k-th step.
        friction: 'exact' (set-valued, event-driven; default) or 'smooth' (tanh(w/smooth_eps)).
        parallel: spread the batch over all cores (numba threads).
    """
    cfg = parse_configuration(config)
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
    P = _params_matrix(params, B)
    U_cmd = _input_matrix(u, B, n_steps, dt)
    U = _apply_input_delay(U_cmd, P, dt)
    if x0 is None:
        Y = np.stack([initial_state(alpha0=a) for a in np.broadcast_to(np.asarray(alpha0, dtype=float), (B,))])
    else:
        Y = np.array(np.broadcast_to(np.asarray(x0, dtype=np.float64), (B, N_STATE)))
        if not np.all(np.isfinite(Y)):
            raise ValueError("initial state contains NaN or inf")
    if cfg.lateral_free is False:
        Y[:, 4:8] = 0.0
    MODE = np.zeros((B, 2), dtype=np.int64)
    n_rec = n_steps // record_every + 1
    OUT = np.empty((B, n_rec, N_OUT))
    A, b, c = tableau(method)
    eps = _friction_eps(friction, smooth_eps)
    if B >= LANES_MIN_BATCH and lanes_eligible(int(cfg), method, eps, P):
        _run_lanes(Y, MODE, U, P, int(cfg), float(dt), int(record_every), OUT, n_steps, parallel)
    else:
        runner = run_batch_parallel if parallel else run_batch_serial
        runner(Y, MODE, U, P, int(cfg), float(dt), np.zeros(B), eps, A, b, c, int(record_every), OUT, True)
    if U is not U_cmd:  # input_delay: the motor saw the delayed voltage, the record keeps the commanded one
        OUT[:, :, 1] = U_cmd[:, np.minimum(np.arange(n_rec) * record_every, n_steps - 1)]
    plist = [RigParams.from_vector(P[k]) for k in range(B)] if B <= 64 or params is not None else [RigParams()] * B
    return BatchTrajectory(cfg, plist, float(dt), method, OUT)


def simulate(config: "str | Configuration", u: InputLike, duration: float, *, dt: float = DEFAULT_DT,
             params: RigParams | None = None, x0: np.ndarray | None = None, alpha0: float = 0.0,
             method: str = "rk4", record_every: int = 1, friction: str = "exact",
             smooth_eps: float = DEFAULT_SMOOTH_EPS) -> Trajectory:
    """Simulate one trajectory (see :func:`simulate_batch` for the arguments)."""
    if params is not None and not isinstance(params, RigParams):
        raise TypeError("simulate() takes one RigParams; use simulate_batch for several")
    if x0 is not None and np.ndim(x0) != 1:
        raise ValueError("simulate() takes one initial state of shape (N_STATE,)")
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) > 1:
        raise ValueError("simulate() takes a scalar or one input sequence; use simulate_batch for several")
    if not callable(u) and not isinstance(u, tuple) and np.ndim(u) == 1:
        u = np.asarray(u, dtype=np.float64)[None, :]  # one per-step sequence
    batch = simulate_batch(config, u, duration, dt=dt, params=params, x0=x0, alpha0=alpha0, n_batch=1,
                           method=method, record_every=record_every, friction=friction, smooth_eps=smooth_eps)
    return batch[0]


class BatchSimulator:
    """Stateful stepping of N trajectories (for environments, controllers, the emulator).

    >>> sim = BatchSimulator("torsional", n=256)
    >>> sim.reset(alpha0=np.zeros(256))
    >>> sim.advance(np.full(256, 2.0), n_steps=10)   # one 10 ms control period at dt = 1 ms
    >>> sim.omega_l, sim.stuck_l, sim.friction[:, 1]
    """

    def __init__(self, config: "str | Configuration", n: int = 1, *, params: ParamsLike = None,
                 dt: float = DEFAULT_DT, method: str = "rk4", friction: str = "exact",
                 smooth_eps: float = DEFAULT_SMOOTH_EPS) -> None:
        self.config = parse_configuration(config)
        if int(n) < 1:
            raise ValueError("n must be >= 1")
        self.n = int(n)
        self.dt = float(dt)
        self.method = method
        self._tab = tableau(method)
        self._eps = _friction_eps(friction, smooth_eps)
        self.P = _params_matrix(params, self.n)
        self.Y = np.zeros((self.n, N_STATE))
        self.MODE = np.zeros((self.n, 2), dtype=np.int64)
        self.T = np.zeros(self.n)
        self.FRIC = np.zeros((self.n, 2))
        self._no_record = np.zeros((self.n, 0, N_OUT))

    def set_params(self, params: ParamsLike, index: "int | np.ndarray | slice | None" = None) -> None:
        """Replace the parameters of all (index None) or some trajectories."""
        sel = slice(None) if index is None else index
        m = len(np.arange(self.n)[sel])
        self.P[sel] = _params_matrix(params, m)

    def reset(self, index: "int | np.ndarray | slice | None" = None, *, alpha0: "float | np.ndarray" = 0.0,
              x0: np.ndarray | None = None) -> None:
        """Put (some) trajectories at rest with winding alpha0 (or at states x0), t = 0."""
        sel = np.arange(self.n)[slice(None) if index is None else index]
        sel = np.atleast_1d(sel)
        if x0 is None:
            Y = np.zeros((len(sel), N_STATE))
            a = np.broadcast_to(np.asarray(alpha0, dtype=float), (len(sel),))
            Y[:, 1] = a
        else:
            Y = np.array(np.broadcast_to(np.asarray(x0, dtype=float), (len(sel), N_STATE)))
        if not self.config.lateral_free:
            Y[:, 4:8] = 0.0
        self.Y[sel] = Y
        self.T[sel] = 0.0
        self.MODE[sel, 0] = np.sign(Y[:, 2]).astype(np.int64)
        self.MODE[sel, 1] = np.sign(Y[:, 3]).astype(np.int64)

    def advance(self, u: "float | np.ndarray", n_steps: int = 1) -> None:
        """Hold voltage u (V, scalar or (n,)) for n_steps integration steps."""
        uu = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=np.float64), (self.n,)))
        if not np.all(np.isfinite(uu)):
            raise ValueError("voltage is NaN or inf")
        if self.n >= LANES_MIN_BATCH and lanes_eligible(int(self.config), self.method, self._eps, self.P):
            lanes_run(self.Y, self.MODE, uu[:, None], self.P, int(self.config), self.dt, self.T, 1,
                      self._no_record, int(n_steps), False, self.FRIC)
            self.T += int(n_steps) * self.dt
            return
        A, b, c = self._tab
        advance_batch(self.Y, self.MODE, uu, self.P, int(self.config), self.dt, int(n_steps), self.T,
                      self._eps, A, b, c, self.FRIC)

    def kernel_args(self, u: np.ndarray, n_steps: int) -> tuple:
        """Arguments of the compiled :func:`drillgym.integrators.advance_batch` for holding ``u``
        over ``n_steps`` (for callers that fuse it into their own compiled loop, e.g. the envs)."""
        A, b, c = self._tab
        return (self.Y, self.MODE, u, self.P, int(self.config), self.dt, int(n_steps), self.T, self._eps, A, b, c,
                self.FRIC)

    # convenient views -------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        return self.Y

    def __getattr__(self, name: str) -> np.ndarray:
        if name in _STATE_INDEX and "Y" in self.__dict__:
            return self.Y[:, _STATE_INDEX[name]]
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


_STATE_INDEX = {n: i for i, n in enumerate(STATE_NAMES)}
