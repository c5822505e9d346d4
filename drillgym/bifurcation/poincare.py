"""Poincare return map of the non-smooth rig, on the core's exact event-driven integrator.

Section: ``omega_l = omega_s(u) + offset`` crossed upwards (d omega_l / dt > 0); omega_s is the
slip equilibrium's speed, ``offset`` (default 0) lets the continuation move the section away from a
local extremum of omega_l along the orbit (see :mod:`.continuation`).  The
flow between two crossings is the core's fixed-step hybrid RK step
(:func:`drillgym.integrators.hybrid_step`, exact stick with located
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

import math

import numpy as np
from numba import njit, prange

from ..configurations import N_STATE, Configuration
from ..dynamics import S_TL, S_TU, S_VX, S_VY, S_WL, S_WU, S_X, S_Y
from ..integrators import alloc_work, hybrid_step, initial_modes, tableau

# columns of the per-flow summary returned by flow_to_section
F_OK, F_T, F_WL_MIN, F_WL_MAX, F_R_MIN, F_R_MAX, F_STICK = 0, 1, 2, 3, 4, 5, 6
N_SUMMARY = 7
REFINE_ITERATIONS = 30


@njit(cache=True)
def _copy_step_state(y, k1, fric, mode, y_to, k1_to, fric_to, mode_to):
    """Copy what hybrid_step carries between steps (state, derivative, friction, modes)."""
    for i in range(N_STATE):
        y_to[i] = y[i]
        k1_to[i] = k1[i]
    fric_to[0] = fric[0]
    fric_to[1] = fric[1]
    mode_to[0] = mode[0]
    mode_to[1] = mode[1]


@njit(cache=True)
def flow_to_section(y, u, ws, p, cfg, dt, t_max, A, b, c):
    """Integrate from state ``y`` (on or off the section) to the next upward crossing of omega_l = ws.

    ``y`` is overwritten by the state at the crossing.  Returns a summary
    vector (ok, return time, min/max omega_l, min/max r, stuck time of the lower disc).
    """
    out = np.zeros(N_SUMMARY)
    K, ytmp, k1, ynew, fric, ftmp, g0, g1 = alloc_work(b.shape[0])
    mode = np.zeros(2, dtype=np.int64)
    ys = np.zeros(N_STATE)
    ks = np.zeros(N_STATE)
    fs = np.zeros(2)
    ms = np.zeros(2, dtype=np.int64)
    t = 0.0
    initial_modes(t, y, u, p, cfg, mode, k1, fric)
    armed = False
    wl_min = y[S_WL]
    wl_max = y[S_WL]
    r0 = math.sqrt(y[S_X] ** 2 + y[S_Y] ** 2)
    r_min = r0
    r_max = r0
    stick = 0.0
    n_max = int(t_max / dt) + 1
    for _ in range(n_max):
        _copy_step_state(y, k1, fric, mode, ys, ks, fs, ms)  # snapshot: the crossing is re-stepped from here
        gprev = y[S_WL] - ws
        hybrid_step(t, y, k1, fric, mode, u, p, cfg, 0.0, dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
        gnew = y[S_WL] - ws
        if mode[1] == 0:
            stick += dt
        if gnew < 0.0:
            armed = True
        elif armed and gprev < 0.0:
            # locate the crossing inside this step (Illinois on the step fraction)
            ta, ga, tb, gb = 0.0, gprev, 1.0, gnew
            side = 0
            tau = 1.0
            for _it in range(REFINE_ITERATIONS):
                tau = (ta * gb - tb * ga) / (gb - ga)
                _copy_step_state(ys, ks, fs, ms, y, k1, fric, mode)
                hybrid_step(t, y, k1, fric, mode, u, p, cfg, 0.0, tau * dt, A, b, c, K, ytmp, ynew, g0, g1, ftmp)
                gt = y[S_WL] - ws
                if abs(gt) < 1e-13 or (tb - ta) < 1e-15:
                    break
                if gt > 0.0:
                    tb, gb = tau, gt
                    if side == 1:
                        ga *= 0.5
                    side = 1
                else:
                    ta, ga = tau, gt
                    if side == -1:
                        gb *= 0.5
                    side = -1
            t += tau * dt
            out[F_OK] = 1.0
            out[F_T] = t
            break
        t += dt
        w = y[S_WL]
        if w < wl_min:
            wl_min = w
        if w > wl_max:
            wl_max = w
        r = math.sqrt(y[S_X] ** 2 + y[S_Y] ** 2)
        if r < r_min:
            r_min = r
        if r > r_max:
            r_max = r
    out[F_WL_MIN] = wl_min
    out[F_WL_MAX] = wl_max
    out[F_R_MIN] = r_min
    out[F_R_MAX] = r_max
    out[F_STICK] = stick
    return out


@njit(cache=True, parallel=True)
def flow_batch(Y, U, WS, P, cfg, dt, t_max, A, b, c, OUT):
    """flow_to_section for every row of Y (B, N_STATE) in parallel; Y overwritten, OUT (B, N_SUMMARY)."""
    for k in prange(Y.shape[0]):
        OUT[k] = flow_to_section(Y[k], U[k], WS[k], P[k], cfg, dt, t_max, A, b, c)


class SectionMap:
    """The Poincare map of ``config`` on the section omega_l = omega_s(u), in reduced coordinates.

    ``omega_s`` is a function of the voltage u (V) returning the section speed
    (rad/s); by default the speed of the slip equilibrium at u.  Coordinates
    ``z`` are the names in :attr:`coords` scaled by :attr:`scale` (so that all
    are O(1): x, y in mm, vx, vy in cm/s).
    """

    def __init__(self, config: Configuration, params_vector: np.ndarray, omega_s, dt: float = 1e-3,
                 t_max: float = 120.0, method: str = "rk4", offset: float = 0.0) -> None:
        self.config = config
        self.offset = float(offset)  # rad/s: the section is omega_l = omega_s(u) + offset
        self.method = method
        self.p = np.ascontiguousarray(params_vector, dtype=np.float64)
        self.omega_s = omega_s
        self.dt = float(dt)
        self.t_max = float(t_max)
        self.tab = tableau(method)
        if config.lateral_free:
            self.coords = ("alpha", "omega_u", "x", "y", "vx", "vy")
            self.scale = np.array([1.0, 1.0, 1e-3, 1e-3, 1e-2, 1e-2])
        else:
            self.coords = ("alpha", "omega_u")
            self.scale = np.array([1.0, 1.0])
        self._idx = {"omega_u": S_WU, "x": S_X, "y": S_Y, "vx": S_VX, "vy": S_VY}

    def level(self, u: float) -> float:
        """Section speed (rad/s) at voltage u: omega_s(u) + offset."""
        return float(self.omega_s(u)) + self.offset

    def with_offset(self, offset: float) -> "SectionMap":
        """The same map on the shifted section omega_l = omega_s(u) + offset (rad/s)."""
        return SectionMap(self.config, self.p, self.omega_s, dt=self.dt, t_max=self.t_max, method=self.method,
                          offset=offset)

    @property
    def dim(self) -> int:
        return len(self.coords)

    def to_state(self, z: np.ndarray, u: float) -> np.ndarray:
        """Full simulator state on the section for reduced (scaled) coordinates z at voltage u."""
        y = np.zeros(N_STATE)
        v = np.asarray(z) * self.scale
        y[S_TL] = v[0]
        for name, val in zip(self.coords[1:], v[1:]):
            y[self._idx[name]] = val
        y[S_WL] = self.level(u)
        y[8] = u
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
        """Flow full states Y (B, N_STATE) at voltages U to the section: (reduced images, summaries)."""
        Y = np.array(Y, dtype=np.float64)
        U = np.ascontiguousarray(U, dtype=np.float64)
        WS = np.array([self.level(u) for u in U])
        P = np.ascontiguousarray(np.repeat(self.p[None, :], len(U), axis=0))
        OUT = np.zeros((len(U), N_SUMMARY))
        A, b, c = self.tab
        flow_batch(Y, U, WS, P, int(self.config), self.dt, self.t_max, A, b, c, OUT)
        return np.stack([self.from_state(y) for y in Y]), OUT

    def find_on_orbit(self, y0: np.ndarray, u: float, transient: float) -> np.ndarray:
        """Simulate ``transient`` seconds from the state y0 at voltage u, then flow to the section:
        reduced coordinates of the point where the attractor crosses it (a shooting start)."""
        from ..simulator import simulate

        traj = simulate(self.config, u, transient, dt=self.dt, x0=y0)
        Z, S = self.flow_states(traj.final_state[None, :], np.array([u]))
        if S[0, F_OK] == 0:
            raise RuntimeError(f"no return to the section omega_l = {self.level(u):.4g} rad/s at u = {u} V "
                               f"within {self.t_max} s (no oscillation to follow)")
        return Z[0]
