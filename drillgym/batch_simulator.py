"""Stateful stepping of many runs: :class:`BatchSimulator`, the interface of the environments,
the controllers' harness and the rig emulator (state kept between calls)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit

from .configurations import N_STATE, Configuration, parse_configuration
from .effects.composition import compose
from .errors import InputError, SimulationError
from .integrators import ADAPTIVE, DEFAULT_DT, tableau
from .lane_runner import LANES_MIN_BATCH, block_width, pad_lanes
from .run_setup import DEFAULT_SMOOTH_EPS, ParamsLike, delay_lines, friction_eps, initial_states, whole_number
from .trajectory import check_run, speed_limit

__all__ = ["BatchSimulator"]


@njit(cache=True)
def _diverged(Y, speed_limit):
    """True when a mechanical state of ``Y`` (n, n_state) is not finite or a disc speed exceeds ``speed_limit``
    (rad/s). The effects' states are left out: a lag's state is NaN until the first step sets it from the
    command, and a broken effect shows in the mechanical states within a step."""
    for k in range(Y.shape[0]):
        for i in range(N_STATE):
            if not np.isfinite(Y[k, i]):
                return True
        if abs(Y[k, 2]) > speed_limit or abs(Y[k, 3]) > speed_limit:
            return True
    return False


class BatchSimulator:
    """Stateful stepping of N runs (for environments, controllers, the emulator).

    ``effects``/``effect_params`` as :func:`drillgym.simulate_batch`: the same compiled
    composition, so a batch stepped here matches a single run of the same model (delays and lags
    included). Batches of :data:`drillgym.lane_runner.LANES_MIN_BATCH` runs or more with exact
    friction step on the SIMD lane kernel.

    Parameters
    ----------
    config : str or Configuration
        ``"upper"``, ``"torsional"``, ``"lateral"``, ``"coupled"`` or ``"free_vibration"``.
    n : int, optional
        Number of runs. Default 1.
    params : RigParams, list of RigParams or numpy.ndarray, optional
        Parameters of all runs, of each, or a parameter matrix ``(n, n_params)``.
    dt : float, optional
        Integration step (s). Default 1 ms.
    method : str, optional
        Fixed-step method, ``"rk4"`` (default) or ``"dp5"``.
    friction : str, optional
        ``"exact"`` (set-valued, default) or ``"smooth"``.
    smooth_eps : float, optional
        Speed scale of the smooth friction law (rad/s).
    effects : optional
        Effects added to the base model (see :func:`drillgym.simulate_batch`).
    effect_params : mapping of str to float, optional
        Values of the effects' parameters by name.

    Attributes
    ----------
    Y : numpy.ndarray
        States ``(n, n_state)``; the state names are attributes too (``sim.omega_l``).
    MODE : numpy.ndarray
        Friction modes ``(n, 2)`` of the upper and lower disc (0 = stuck, +-1 = slipping).
    T : numpy.ndarray
        Time of each run since its reset (s).
    P : numpy.ndarray
        Parameter matrix ``(n, n_params)``.

    Raises
    ------
    InputError
        ``n < 1``, an adaptive method, or an unknown friction model.

    Examples
    --------
    >>> sim = BatchSimulator("torsional", n=256)
    >>> sim.reset(alpha0=np.zeros(256))
    >>> sim.advance(np.full(256, 2.0), n_steps=10)   # one 10 ms control period at dt = 1 ms
    >>> sim.omega_l, sim.stuck_l, sim.friction[:, 1]
    """

    def __init__(
        self,
        config: str | Configuration,
        n: int = 1,
        *,
        params: ParamsLike = None,
        dt: float = DEFAULT_DT,
        method: str = "rk4",
        friction: str = "exact",
        smooth_eps: float = DEFAULT_SMOOTH_EPS,
        effects: Any = None,
        effect_params: Mapping[str, float] | None = None,
    ) -> None:
        self.config = parse_configuration(config)
        n = whole_number("n", n, 1)
        self.composition, self.effect_values = compose(effects, effect_params)
        self.kernels = self.composition.kernels
        self.n = int(n)
        self.dt = float(dt)
        self.method = method
        if method.lower() in ADAPTIVE:
            raise InputError(f"BatchSimulator steps on a fixed grid: method 'rk4' or 'dp5', not {method!r}")
        self._tab = tableau(method)
        self._eps = friction_eps(friction, smooth_eps)
        self.P = self.composition.matrix(params, self.n, self.effect_values)
        self.Y = initial_states(self.composition, self.n, None, 0.0)
        self.MODE = np.zeros((self.n, 2), dtype=np.int64)
        self.T = np.zeros(self.n)
        self.FRIC = np.zeros((self.n, 2))
        self.HIST, self.HEAD = delay_lines(self.composition, self.P, self.dt)
        # sample-major, no samples; as many lanes as the lane kernel runs (whole blocks: :meth:`_advance_lanes`)
        self._no_record = np.zeros((0, len(self.composition.output_names), block_width(self.n)))
        self._pad: list[np.ndarray] | None = None  # the lane kernel's padded buffers, reused
        self._lanes = self.n >= LANES_MIN_BATCH and self._eps == 0.0
        self._speed_limit = float(speed_limit(self.P).min())  # rad/s, the smallest over the runs (:meth:`_check`)

    def set_params(self, params: ParamsLike, index: int | np.ndarray | slice | None = None) -> None:
        """Replace the parameters of all or some runs.

        Parameters
        ----------
        params : RigParams, list of RigParams or numpy.ndarray
            The new parameters (one set for all selected runs, or one per run).
        index : int, array of int or slice, optional
            The runs to change; None changes all.
        """
        sel = slice(None) if index is None else index
        m = len(np.arange(self.n)[sel])
        self.P[sel] = self.composition.matrix(params, m, self.effect_values)
        self._speed_limit = float(speed_limit(self.P).min())
        self._resize_delay_lines()

    def _resize_delay_lines(self) -> None:
        L = self.composition.delay_line_length(self.P, self.dt)
        if L > self.HIST.shape[1]:  # longer delays: a longer line (contents kept, oldest first)
            H = np.zeros((self.n, L))
            for k in range(self.n):
                h = self.HEAD[k]
                if h >= 0:
                    old = np.roll(self.HIST[k], -(h + 1))  # oldest ... newest
                    H[k, L - old.size :] = old
                    H[k, : L - old.size] = old[0]
                    self.HEAD[k] = L - 1
            self.HIST = H

    def reset(
        self,
        index: int | np.ndarray | slice | None = None,
        *,
        alpha0: float | np.ndarray = 0.0,
        x0: np.ndarray | None = None,
    ) -> None:
        """Put runs at rest with winding ``alpha0`` (or at states ``x0``), at t = 0.

        The delay lines are emptied: before the first command the motor saw it held.

        Parameters
        ----------
        index : int, array of int or slice, optional
            The runs to reset; None resets all.
        alpha0 : float or numpy.ndarray, optional
            Initial winding (rad), scalar or per run.
        x0 : numpy.ndarray, optional
            Initial states instead of rest (see :func:`drillgym.run_setup.initial_states`).
        """
        sel = np.arange(self.n)[slice(None) if index is None else index]
        sel = np.atleast_1d(sel)
        Y = initial_states(self.composition, len(sel), x0, alpha0)
        if not self.config.lateral_free:
            Y[:, 4:8] = 0.0
        self.Y[sel] = Y
        self.T[sel] = 0.0
        self.HEAD[sel] = -1
        self.MODE[sel, 0] = np.sign(Y[:, 2]).astype(np.int64)
        self.MODE[sel, 1] = np.sign(Y[:, 3]).astype(np.int64)

    def advance(self, u: float | np.ndarray, n_steps: int = 1) -> None:
        """Hold a command for a number of integration steps.

        Parameters
        ----------
        u : float or numpy.ndarray
            Motor voltage (V), scalar or one per run ``(n,)``.
        n_steps : int, optional
            Integration steps to hold it. Default 1.

        Raises
        ------
        InputError
            A voltage is NaN or infinite.
        SimulationError
            A run diverged: a state is not finite or a disc speed exceeds
            :func:`drillgym.trajectory.speed_limit` (names the run, the time and the state).
        """
        uu = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=np.float64), (self.n,)))
        if not np.all(np.isfinite(uu)):
            raise InputError("voltage is NaN or inf")
        t_start = float(self.T.min())
        try:
            if self._lanes and n_steps > 0:
                self._advance_lanes(uu, int(n_steps))
                self.T += int(n_steps) * self.dt
            else:
                self._advance_scalar(uu, int(n_steps))
        except (ZeroDivisionError, OverflowError, FloatingPointError) as exc:  # the compiled model on a wild state
            raise SimulationError(
                f"a run diverged after t = {t_start:.6g} s: the compiled model failed ({exc}) with the effects "
                f"{self.composition.label}; check the parameters and the initial state"
            ) from None
        if n_steps > 0:
            self._check()

    def _advance_scalar(self, uu: np.ndarray, n_steps: int) -> None:
        """The scalar stepping kernel over all runs (small batches, smooth friction)."""
        A, b, c = self._tab
        self.kernels.stepping.advance_batch(
            self.Y,
            self.MODE,
            np.require(uu, np.float64, ("C", "W")),  # a read-only command would compile a second signature
            self.P,
            int(self.config),
            self.dt,
            n_steps,
            self.T,
            self._eps,
            A,
            b,
            c,
            self.FRIC,
            self.HIST,
            self.HEAD,
        )

    def _check(self) -> None:
        """Raise :class:`SimulationError` when a run diverged (a few us when none did).

        The fast test compares the speeds with the smallest limit of the parameters last seen; when it
        fails, the limits are taken anew from ``P`` (which callers may have changed) for the verdict.
        """
        Y = self.Y
        if not _diverged(Y, self._speed_limit):
            return
        names, label = self.composition.full_state_names[:N_STATE], self.composition.label
        check_run(np.empty((self.n, 0, 0)), (), Y[:, :N_STATE], names, self.P, self.T, self.dt, 1, label, self.T)
        self._speed_limit = float(speed_limit(self.P).min())  # no run diverged: the parameters had changed

    def _advance_lanes(self, uu: np.ndarray, n_steps: int) -> None:
        """The lane kernel on whole blocks of lanes, as :func:`drillgym.lane_runner.run_lanes`.

        The runs past the last whole block step beside copies of the last one, so every lane takes
        the vectorised loop bodies and a run does not depend on how many are stepped with it.
        """
        n, width = self.n, self._no_record.shape[2]
        arrays = [self.Y, self.MODE, uu[:, None], self.P, self.T, self.FRIC, self.HIST, self.HEAD]
        if width != n:
            self._pad = arrays = pad_lanes(arrays, width, self._pad)
        Y, MODE, U, P, T, FRIC, HIST, HEAD = arrays
        self.kernels.lanes.lanes_run(
            Y,
            MODE,
            U,
            P,
            int(self.config),
            self.dt,
            T,
            1,
            self._no_record,
            n_steps,
            False,
            FRIC,
            HIST,
            HEAD,
            *self._tab,
        )
        if width != n:
            self.Y[:], self.MODE[:], self.FRIC[:], self.HIST[:], self.HEAD[:] = (
                Y[:n],
                MODE[:n],
                FRIC[:n],
                HIST[:n],
                HEAD[:n],
            )

    def kernel_args(self, u: np.ndarray, n_steps: int) -> tuple:
        """Arguments of the composition's compiled ``stepping.advance_batch``.

        For callers that fuse the stepping into their own compiled loop (e.g. the environments).

        Parameters
        ----------
        u : numpy.ndarray
            Motor voltage (V) of each run ``(n,)``.
        n_steps : int
            Integration steps to hold it.

        Returns
        -------
        tuple
            The positional arguments of ``advance_batch``.
        """
        A, b, c = self._tab
        return (
            self.Y,
            self.MODE,
            u,
            self.P,
            int(self.config),
            self.dt,
            int(n_steps),
            self.T,
            self._eps,
            A,
            b,
            c,
            self.FRIC,
            self.HIST,
            self.HEAD,
        )

    # views of the state -------------------------------------------------------
    @property
    def state(self) -> np.ndarray:
        """States ``(n, n_state)`` (the array itself, not a copy)."""
        return self.Y

    def __getattr__(self, name: str) -> np.ndarray:
        if "Y" in self.__dict__ and "composition" in self.__dict__:
            names = self.composition.full_state_names
            if name in names:
                return self.Y[:, names.index(name)]
        raise AttributeError(name)

    @property
    def alpha(self) -> np.ndarray:
        """Winding ``theta_l - theta_u`` of each run (rad)."""
        return self.Y[:, 1] - self.Y[:, 0]

    @property
    def lateral_fixed(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) of the lower disc centre in the fixed frame (m)."""
        c, s = np.cos(self.Y[:, 0]), np.sin(self.Y[:, 0])
        return self.Y[:, 4] * c - self.Y[:, 5] * s, self.Y[:, 4] * s + self.Y[:, 5] * c

    @property
    def friction(self) -> np.ndarray:
        """Friction torques ``(Tfu, Tfl)`` (N m) at the current state, shape ``(n, 2)``."""
        return self.FRIC

    @property
    def stuck_u(self) -> np.ndarray:
        """True where the upper disc sticks."""
        return self.MODE[:, 0] == 0

    @property
    def stuck_l(self) -> np.ndarray:
        """True where the lower disc sticks."""
        return self.MODE[:, 1] == 0
