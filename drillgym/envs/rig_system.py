"""The physical system behind the environments: N rigs in one batched compiled core.

``RigSystem`` wraps :class:`drillgym.BatchSimulator` (the same event-driven
kernels as :func:`drillgym.simulate`) and adds what an environment needs and the
core does not: a lean per-control-period step (preallocated arrays, the compiled
``advance_batch`` called directly, no per-step validation: the env validates the
action once) and per-episode domain randomisation of the parameters.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..effects.composition import Composition
from ..params import RigParams
from ..simulator import BatchSimulator

__all__ = ["RigSystem", "ParameterRandomizer"]


class ParameterRandomizer:
    """Draws parameter vectors uniformly in ``value * (1 +/- fraction)`` for the named parameters
    (base or effect parameters of the composition), clipped to each parameter's physical bounds."""

    def __init__(self, base: np.ndarray, fraction: float, names: Sequence[str], composition: Composition) -> None:
        self.base = np.array(base, dtype=np.float64)
        self.fraction = float(fraction)
        self.index = np.array([composition.param_index(n) for n in names], dtype=np.int64)
        prm = [composition.parameter(n) for n in names]
        self.lo = np.array([p.lo for p in prm], dtype=np.float64)
        self.hi = np.array([p.hi for p in prm], dtype=np.float64)

    @property
    def active(self) -> bool:
        return self.fraction > 0 and self.index.size > 0

    def sample(self, rng: np.random.Generator, omega_ref: float | None = None) -> np.ndarray:
        """One parameter vector (the composition's kernel layout); ``omega_ref`` (rad/s, the episode's
        target, drawn first) is not used here: a randomizer may draw its rig depending on it."""
        p = self.base.copy()
        v = p[self.index] * (1.0 + rng.uniform(-self.fraction, self.fraction, self.index.size))
        p[self.index] = np.minimum(np.maximum(v, self.lo), self.hi)
        return p


class RigSystem:
    """N copies of one rig configuration, stepped one control period at a time.

    State views (arrays of shape (n,), SI units): ``omega_u``, ``omega_l``, ``alpha``,
    ``theta_u``, ``theta_l``; ``Y`` is the (n, n_state) state matrix (the 8 mechanical states of
    :mod:`drillgym.configurations`, then the effects' states), ``friction_l`` the lower friction torque (N m),
    ``stuck_l`` the lower disc's stick flag.

    Parameters
    ----------
    configuration : str
        'torsional', 'lateral' or 'coupled'.
    n : int
        Number of rigs.
    params : RigParams, optional
        Parameter set of every rig (default the identified set).
    dt : float, optional
        Integration step (s).
    n_substeps : int, optional
        Integration steps per control period (voltage held constant over them).
    method, friction : str, optional
        Integration method and friction treatment, as :class:`drillgym.BatchSimulator`.
    effects, effect_params : optional
        Effects of every rig and their parameter values, as :class:`drillgym.BatchSimulator`.
    """

    def __init__(
        self,
        configuration: str,
        n: int,
        *,
        params: RigParams | None = None,
        dt: float = 1e-2,
        n_substeps: int = 1,
        method: str = "rk4",
        friction: str = "exact",
        effects=None,
        effect_params=None,
    ) -> None:
        self.sim = BatchSimulator(
            configuration,
            n,
            params=params,
            dt=dt,
            method=method,
            friction=friction,
            effects=effects,
            effect_params=effect_params,
        )
        self.composition = self.sim.composition
        self._advance = self.sim.kernels.stepping.advance_batch
        self.n = self.sim.n
        self.n_substeps = int(n_substeps)
        self.control_dt = self.sim.dt * self.n_substeps
        self.u = np.zeros(self.n)  # voltage applied over the current period (V)
        # kernel arguments, bound once (BatchSimulator.advance re-validates on every call)
        self._args = self.sim.kernel_args(self.u, self.n_substeps)

    # ------------------------------------------------------------------------ stepping
    def step(self) -> None:
        """Advance every rig by one control period holding the voltages ``self.u``
        (finite, already clipped to the amplifier range by the caller)."""
        self._advance(*self.kernel_args)

    @property
    def kernel_args(self) -> tuple:
        """Arguments of the composition's compiled ``advance_batch`` for one control period
        (persistent arrays, updated in place): Y, MODE, u, P, cfg, dt, n_substeps, T, eps, A, b, c, FRIC,
        HIST, HEAD."""
        return self._args

    def reset(self, index: np.ndarray, alpha0: np.ndarray, params: np.ndarray | None = None) -> None:
        """Rigs ``index`` at rest with winding ``alpha0`` (rad), t = 0, optionally new parameter rows
        (a longer drawn delay lengthens the delay lines: :attr:`kernel_args` is then rebound)."""
        if params is not None:
            self.sim.P[index] = params
            if self.composition.has_delay:
                hist = self.sim.HIST
                self.sim.set_params(params, index)  # resizes the delay lines when a row needs it
                if self.sim.HIST is not hist:
                    self._args = self.sim.kernel_args(self.u, self.n_substeps)
        self.sim.reset(index, alpha0=alpha0)
        self.u[index] = 0.0
        # friction torques (holding torques) of the rest state: a zero-length advance on a copy
        s = self.sim
        _, _, _, _, cfg, dt, _, _, eps, A, b, c, _, _, _ = self._args
        Y, MODE, FRIC = s.Y[index].copy(), s.MODE[index].copy(), s.FRIC[index].copy()
        self._advance(
            Y,
            MODE,
            self.u[index],
            s.P[index],
            cfg,
            dt,
            0,
            s.T[index].copy(),
            eps,
            A,
            b,
            c,
            FRIC,
            s.HIST[index].copy(),
            s.HEAD[index].copy(),
        )
        s.FRIC[index] = FRIC

    # ------------------------------------------------------------------------ views
    @property
    def Y(self) -> np.ndarray:
        return self.sim.Y

    @property
    def t(self) -> np.ndarray:
        return self.sim.T

    @property
    def theta_u(self) -> np.ndarray:
        return self.sim.Y[:, 0]

    @property
    def theta_l(self) -> np.ndarray:
        return self.sim.Y[:, 1]

    @property
    def omega_u(self) -> np.ndarray:
        return self.sim.Y[:, 2]

    @property
    def omega_l(self) -> np.ndarray:
        return self.sim.Y[:, 3]

    @property
    def alpha(self) -> np.ndarray:
        return self.sim.alpha

    @property
    def lateral_fixed(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) of the lower disc centre in the fixed (LVDT) frame (m)."""
        return self.sim.lateral_fixed

    @property
    def friction_l(self) -> np.ndarray:
        return self.sim.FRIC[:, 1]

    @property
    def stuck_l(self) -> np.ndarray:
        return self.sim.MODE[:, 1] == 0

    @property
    def params_matrix(self) -> np.ndarray:
        return self.sim.P
