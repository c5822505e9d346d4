"""Poincare return map of the non-smooth rig, on the core's exact event-driven integrator.

Section: ``omega_l = omega_s(u) + offset`` crossed upwards (d omega_l / dt > 0); omega_s is the
slip equilibrium's speed, ``offset`` (default 0) lets the continuation move the section away from a
local extremum of omega_l along the orbit (see :mod:`.continuation`).  The
flow between two crossings is the core's fixed-step hybrid RK step
(the composition's ``hybrid_step``, :mod:`.flows`, exact stick with located
stick/slip events), so stick phases inside an orbit are handled exactly; the
final crossing is located inside its step by the Illinois method (re-stepping
from the step's start with a fractional step), so the return point and time
are smooth functions of the initial point between stick/slip events and the
finite-difference monodromy is accurate (see :mod:`.shooting`).

The section map works on *reduced* coordinates (the dynamics do not depend on
theta_u, only on alpha = theta_l - theta_u): ``alpha, omega_u`` and, for the
lateral configurations, ``x, y, vx, vy`` (co-rotating frame); omega_l is the
section value.  All flows of one Jacobian evaluation run as one batch,
spread over the cores with numba threads.
"""

from __future__ import annotations

import numpy as np

from ..configurations import Configuration
from ..dynamics import S_TL, S_TU, S_VX, S_VY, S_WL, S_WU, S_X, S_Y
from ..effects.composition import Composition, compose
from ..errors import FitError
from ..integrators import fixed_step_tableau
from .summary import F_OK, F_R_MAX, F_R_MIN, F_STICK, F_T, F_WL_MAX, F_WL_MIN, N_SUMMARY  # noqa: F401


class SectionMap:
    """The Poincare map of ``config`` on the section omega_l = omega_s(u), in reduced coordinates.

    ``omega_s`` is a function of the voltage u (V) returning the section speed
    (rad/s); by default the speed of the slip equilibrium at u.  Coordinates
    ``z`` are the names in :attr:`coords` scaled by :attr:`scale` (so that all
    are O(1): x, y in mm, vx, vy in cm/s).
    """

    def __init__(
        self,
        config: Configuration,
        params_vector: np.ndarray,
        omega_s,
        dt: float = 1e-3,
        t_max: float = 120.0,
        method: str = "rk4",
        offset: float = 0.0,
        composition: Composition | None = None,
    ) -> None:
        self.config = config
        self.composition = composition if composition is not None else compose(None)[0]
        self._flow_batch = self.composition.kernels.client("drillgym.bifurcation.flows").flow_batch
        self.offset = float(offset)  # rad/s: the section is omega_l = omega_s(u) + offset
        self.method = method
        self.p = np.ascontiguousarray(params_vector, dtype=np.float64)
        self.omega_s = omega_s
        self.dt = float(dt)
        self.t_max = float(t_max)
        self.tab = fixed_step_tableau(method, "section map")
        if config.lateral_free:
            self.coords = ("alpha", "omega_u", "x", "y", "vx", "vy")
            self.scale = np.array([1.0, 1.0, 1e-3, 1e-3, 1e-2, 1e-2])
        else:
            self.coords = ("alpha", "omega_u")
            self.scale = np.array([1.0, 1.0])
        self._idx = {"omega_u": S_WU, "x": S_X, "y": S_Y, "vx": S_VX, "vy": S_VY}
        # the effects' states are coordinates of the section too (e.g. the lag's u_m)
        self.coords += self.composition.state_names
        self.scale = np.concatenate([self.scale, np.ones(self.composition.n_states)])
        self._idx.update({n: 8 + j for j, n in enumerate(self.composition.state_names)})

    def level(self, u: float) -> float:
        """Section speed (rad/s) at voltage u: omega_s(u) + offset."""
        return float(self.omega_s(u)) + self.offset

    def with_offset(self, offset: float) -> SectionMap:
        """The same map on the shifted section omega_l = omega_s(u) + offset (rad/s)."""
        return SectionMap(
            self.config,
            self.p,
            self.omega_s,
            dt=self.dt,
            t_max=self.t_max,
            method=self.method,
            offset=offset,
            composition=self.composition,
        )

    @property
    def dim(self) -> int:
        return len(self.coords)

    def to_state(self, z: np.ndarray, u: float) -> np.ndarray:
        """Full simulator state on the section for reduced (scaled) coordinates z at voltage u."""
        y = np.zeros(self.composition.n_state)
        v = np.asarray(z) * self.scale
        y[S_TL] = v[0]
        for name, val in zip(self.coords[1:], v[1:]):
            y[self._idx[name]] = val
        y[S_WL] = self.level(u)
        return y

    def from_state(self, y: np.ndarray) -> np.ndarray:
        """Reduced (scaled) coordinates of a state (alpha = theta_l - theta_u)."""
        v = [y[S_TL] - y[S_TU]] + [y[self._idx[n]] for n in self.coords[1:]]
        return np.asarray(v) / self.scale

    def evaluate(self, Z: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map a batch of points: Z (B, dim) at voltages U (B,) -> (images (B, dim), summaries (B, N_SUMMARY))."""
        Z = np.atleast_2d(Z)
        U = np.asarray(U, dtype=float).reshape(-1)
        Y = np.stack([self.to_state(z, u) for z, u in zip(Z, U)])
        return self.flow_states(Y, U)

    def flow_states(self, Y: np.ndarray, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flow full states Y (B, n_state) at voltages U to the section: (reduced images, summaries)."""
        Y = np.array(Y, dtype=np.float64)
        U = np.ascontiguousarray(U, dtype=np.float64)
        WS = np.array([self.level(u) for u in U])
        P = np.ascontiguousarray(np.repeat(self.p[None, :], len(U), axis=0))
        OUT = np.zeros((len(U), N_SUMMARY))
        A, b, c = self.tab
        self._flow_batch(Y, U, WS, P, int(self.config), self.dt, self.t_max, A, b, c, OUT)
        return np.stack([self.from_state(y) for y in Y]), OUT

    def find_on_orbit(self, y0: np.ndarray, u: float, transient: float) -> np.ndarray:
        """Simulate ``transient`` seconds from the state y0 at voltage u, then flow to the section:
        reduced coordinates of the point where the attractor crosses it (a shooting start)."""
        from ..simulator import simulate_batch

        # any transient: it need not be a whole number of steps, which simulate() refuses
        traj = simulate_batch(
            self.config, u, transient, dt=self.dt, x0=y0, params=self.p, effects=self.composition, n_batch=1
        )[0]
        Z, S = self.flow_states(traj.final_state[None, :], np.array([u]))
        if S[0, F_OK] == 0:
            raise FitError(
                f"no return to the section omega_l = {self.level(u):.4g} rad/s at u = {u} V "
                f"within {self.t_max} s (no oscillation to follow)"
            )
        return Z[0]
