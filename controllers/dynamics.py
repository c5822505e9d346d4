"""The composition as a controller's model: its compiled right-hand side, linearised, read and inverted.

A model-based controller predicts with the model it is given, every effect included, through the
composition's compiled kernels (:mod:`drillgym.effects`): :class:`ModelDynamics` evaluates the torsional
``state_derivative`` of the composition (every Force, Friction on either disc, the Input chain with or
without states; the exact stick logic with a disc at rest below ``eps``) at an estimator's state

    z = (theta_u, omega_u, alpha, omega_l, d, [du], effect states ...)      (rad, rad/s, rad, rad/s, -, N m, ...)

where ``d`` is the brake law's relative level error (``scale``: the brake's Ts, Tc, bb times 1 + d) or a
torque added to it (``offset``, N m) and ``du`` a torque on the upper disc (N m), both estimated, not
modelled.  Its Jacobian is taken numerically around the operating point (central differences with the
friction modes held), so any library effect, user file or discovered candidate reaches the controller
the same way.  The Measurement effects on the motor and lower encoders give the readings and their
Jacobian (:meth:`ModelDynamics.readings`); the static part of the Input chain (a dead zone, an offset:
the voltage at the motor for a command held long enough for the lags to settle) is inverted through its
monotone hull where it is monotone beyond ±0.5 V (:meth:`ModelDynamics.command`), so a controller may ask
for a motor voltage and send the command that gives it.  Delay effects are the controllers' line of past commands
(:func:`controllers.model.delayed_discretisation`); their length is the composition's ``hk_delay``.

Time-dependent effects are evaluated at t = 0 (a controller's run has no origin in the recording).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym.effects import Composition
from drillgym.effects.base import Input
from drillgym.effects.foreign_client import foreign_client
from drillgym.params import IDX

__all__ = ["ModelDynamics", "model_kernels", "lag_arrays", "jacobian_steps", "I_TU", "I_WU", "I_AL", "I_WL", "I_D"]

I_TU, I_WU, I_AL, I_WL, I_D = range(5)
_COMPILED: dict[Composition, Any] = {}


@dataclass(frozen=True)
class _Kernels:
    """The composition's model as numba functions: batched (``rhs``, ``jac``, ``volt``) and per state, for
    compiled callers (a controller's compiled law): ``evaluate`` (dz/dt at one state, the modes resolved or
    held), ``slipping`` (dz/dt and the voltage at the motor with the discs slipping at given speeds) and
    ``lane_jacobian`` (the central-difference Jacobians at one state), ``settled`` (the static input map at one
    state)."""

    rhs: Any
    jac: Any
    volt: Any
    evaluate: Any
    slipping: Any
    lane_jacobian: Any
    settled: Any


def jacobian_steps(nz: int) -> np.ndarray:
    """Central-difference steps of :meth:`ModelDynamics.jacobian`: the nz rows of z, then the command (V)."""
    h = np.full(nz + 1, 1e-5)
    h[I_AL], h[I_TU] = 1e-6, 1e-6
    return h


def model_kernels(comp: Composition) -> _Kernels:
    """Numba functions of the composition's compiled model: its copy of the kernel client template
    :mod:`controllers.compiled.composition_law`, compiled once and then loaded from numba's cache."""
    if comp not in _COMPILED:
        m = foreign_client(comp.kernels, "controllers.compiled.composition_law")
        _COMPILED[comp] = _Kernels(m.rhs, m.jac, m.volt, m.evaluate, m.slipping, m.lane_jacobian, m.settled)
    return _COMPILED[comp]


def lag_arrays(comp: Composition) -> tuple[np.ndarray, np.ndarray]:
    """The columns of the declared first-order lag states after the 8 mechanical ones, and the indices of their time
    constants in the parameter vector (int arrays, in the signal path's order)."""
    cols = np.array([c - 8 for c in comp.lag_state_columns], dtype=np.int64)
    tau = [comp.param_index(t) for e in comp.effects for t in (getattr(e, "lag", None) or {}).values()]
    return cols, np.array(tau, dtype=np.int64)


@dataclass(frozen=True)
class ModelDynamics:
    """A composition with its parameter vector as the right-hand side of an estimator's state (module doc).

    Parameters
    ----------
    composition : Composition
        The model's effects.
    vector : ndarray
        Its parameter vector (base, then effect parameters).
    scale : bool, optional
        ``d`` (row :data:`I_D`) is the brake law's relative level (True) or a torque added to it (N m, False).
    has_du : bool, optional
        Row 5 is a torque on the upper disc (N m).
    eps : float, optional
        A disc slower than this (rad/s) is at rest (the stick logic decides whether it stays there).

    Attributes
    ----------
    e0 : int
        Row of the first effect state (after ``d`` and ``du``).
    nz : int
        Number of rows of z.
    """

    composition: Composition
    vector: np.ndarray
    scale: bool = True
    has_du: bool = False
    eps: float = 1e-3
    e0: int = field(init=False)
    nz: int = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "vector", np.ascontiguousarray(self.vector, dtype=np.float64))
        object.__setattr__(self, "e0", 6 if self.has_du else 5)
        object.__setattr__(self, "nz", self.e0 + self.composition.n_states)
        object.__setattr__(self, "_rows", {})

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the rows of z."""
        return (
            ("theta_u", "omega_u", "alpha", "omega_l", "d")
            + (("du",) if self.has_du else ())
            + tuple(self.composition.state_names)
        )

    @property
    def lag_rows(self) -> dict[int, float]:
        """Rows of z of the declared first-order lag states -> their time constants (s)."""
        comp, out = self.composition, {}
        for e in comp.effects:
            for st, tau in (getattr(e, "lag", None) or {}).items():
                out[self.e0 + comp.state_index(st)] = float(self.vector[comp.param_index(tau)])
        return out

    @property
    def delay(self) -> float:
        """Transport delay of the command (s): the composition's compiled ``hk_delay``; 0 without one."""
        return self.composition.delay(self.vector)

    @property
    def has_input_chain(self) -> bool:
        """True when an Input effect transforms the command."""
        return self.composition.has_kind(Input)

    def _P(self, n: int) -> np.ndarray:
        if n not in self._rows:  # one parameter row per lane, made once per batch size
            self._rows[n] = np.ascontiguousarray(np.tile(self.vector, (n, 1)))
        return self._rows[n]

    def _Z(self, z: np.ndarray) -> np.ndarray:
        z = np.asarray(z, dtype=float)
        return np.ascontiguousarray(z[: self.nz].T if z.ndim == 2 else z[: self.nz][None, :])

    def f(self, z: np.ndarray, v: np.ndarray) -> np.ndarray:
        """dz/dt (rows of z per second, (nz, n)) at states z (>= nz rows, n columns) under commands v (V, (n,))
        entering the Input chain (after any delay)."""
        Z = self._Z(z)
        n = Z.shape[0]
        out = np.zeros((n, self.nz))
        k = model_kernels(self.composition)
        zero = np.zeros(n)
        V = np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), (n,)))
        k.rhs(Z, V, self._P(n), self.e0, 5 if self.has_du else -1, self.scale, self.eps, zero, zero, False, out, zero)
        return out.T

    def jacobian(self, z: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(df/dz (n, nz, nz), df/dv (n, nz)) at states z and commands v, by central differences with the
        friction modes of (z, v) held."""
        Z = self._Z(z)
        n = Z.shape[0]
        J, B = np.zeros((n, self.nz, self.nz)), np.zeros((n, self.nz))
        h = jacobian_steps(self.nz)
        V = np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), (n,)))
        model_kernels(self.composition).jac(
            Z, V, self._P(n), self.e0, 5 if self.has_du else -1, self.scale, self.eps, h, J, B
        )
        return J, B

    def accelerations(self, z: np.ndarray, omega_u: np.ndarray, omega_l: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(dz/dt (nz, n), the voltage at the motor (V, (n,))) at z with the discs slipping at omega_u, omega_l
        (rad/s, (n,)), the command 0 entering the Input chain."""
        Z = self._Z(z)
        n = Z.shape[0]
        out, volt = np.zeros((n, self.nz)), np.zeros(n)
        wu = np.ascontiguousarray(np.broadcast_to(np.asarray(omega_u, dtype=float), (n,)))
        wl = np.ascontiguousarray(np.broadcast_to(np.asarray(omega_l, dtype=float), (n,)))
        model_kernels(self.composition).rhs(
            Z, np.zeros(n), self._P(n), self.e0, 5 if self.has_du else -1, self.scale, self.eps, wu, wl, True, out, volt
        )
        return out.T, volt

    def lower_torque(self, z: np.ndarray, omega_l: np.ndarray, omega_u: np.ndarray | None = None) -> np.ndarray:
        """Torque (N m, (n,)) against the lower disc besides the string's kθ α while it slips at ``omega_l``
        (rad/s): the brake law with its effects, the lower-disc forces and the string's extra torque (at
        ``omega_u``, default the estimate's), with d = 0 (the brake law's own level)."""
        z0 = np.array(z[: self.nz], dtype=float, copy=True)
        z0[I_D] = 0.0
        if self.has_du:
            z0[5] = 0.0
        wu = z0[I_WU] if omega_u is None else omega_u
        a = self.accelerations(z0, wu, omega_l)[0][I_WL]
        p = self.vector
        return -p[IDX.ktheta] * z0[I_AL] - p[IDX.Jl] * a

    def upper_torque(self, z: np.ndarray, omega_u: np.ndarray, omega_l: np.ndarray | None = None) -> np.ndarray:
        """Torque (N m, (n,)) against the upper disc besides the motor and the string's kθ α while it slips at
        ``omega_u`` (rad/s): its friction with the effects, the upper-disc forces and the string's extra torque."""
        z0 = np.array(z[: self.nz], dtype=float, copy=True)
        z0[I_D] = 0.0
        if self.has_du:
            z0[5] = 0.0
        wl = z0[I_WL] if omega_l is None else omega_l
        dz, vm = self.accelerations(z0, omega_u, wl)
        p = self.vector
        return p[IDX.km] * vm + p[IDX.ktheta] * z0[I_AL] - p[IDX.Ju] * dz[I_WU]

    def motor_voltage(self, z: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Voltage at the motor (V, (n,)) for commands u (V) held until the lags settled: the static input map."""
        Z = self._Z(z)
        n = Z.shape[0]
        U = np.ascontiguousarray(np.broadcast_to(np.asarray(u, dtype=float), (n,)))
        out = np.zeros(n)
        model_kernels(self.composition).volt(Z, U, self._P(n), self.e0, out, *lag_arrays(self.composition))
        return out

    def input_map_branches(self, u_max: float) -> tuple[float, tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """(g(0), positive branch, negative branch) of the static input map's monotone hull at rest on ±2 u_max:
        each branch (voltages, commands) increasing in |command|, the last command of each flat stretch kept."""
        key = ("branches", float(u_max))
        if key not in self._rows:
            u = np.linspace(0.0, 2.0 * u_max, 2001)
            z = np.zeros((self.nz, u.size))
            out = []
            for sign in (1.0, -1.0):
                h = np.maximum.accumulate(sign * self.motor_voltage(z, sign * u))  # the hull, |command| growing
                keep = np.append(np.diff(h) > 1e-12, True)
                out.append((h[keep], u[keep]))
            g0 = float(self.motor_voltage(np.zeros((self.nz, 1)), np.zeros(1))[0])
            self._rows[key] = (g0, out[0], out[1])
        return self._rows[key]

    def invertible(self, u_max: float = 5.0) -> bool:
        """True when the static input map (a function of the command alone, at rest) changes the command somewhere
        in ±2 u_max (V) and is non-decreasing beyond ±0.5 V: its monotone hull's inverse (:meth:`command`) then
        compensates it (a dead zone, an offset; a fitted map that dips near 0 V is taken as the dead zone it
        makes)."""
        if not self.has_input_chain:
            return False
        u = np.linspace(-2 * u_max, 2 * u_max, 801)
        g = self.motor_voltage(np.zeros((self.nz, u.size)), u)
        outer = np.abs(u[:-1]) >= 0.5
        return bool(np.all(np.diff(g)[outer] >= -1e-9) and np.max(np.abs(g - u)) > 1e-9 and np.ptp(g) > 0)

    def command(self, z: np.ndarray, v_motor: np.ndarray, u_max: float) -> np.ndarray:
        """Commands (V, (n,), within ±2 u_max) whose settled voltage at the motor is ``v_motor`` (V): the monotone hull
        of the static input map inverted (a dead zone: v ± u0; an offset: v − offset; 0 for g(0))."""
        del z  # the map at rest: a function of the command alone
        g0, (hp, up), (hn, un) = self.input_map_branches(u_max)
        v = np.asarray(v_motor, dtype=float)
        pos = np.interp(v, hp, up, left=0.0)
        neg = -np.interp(-v, hn, un, left=0.0)
        return np.where(v > g0, pos, np.where(v < g0, neg, 0.0))

    def readings(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What the motor and lower encoders read (rad, (2, n)) at states z: the Measurement effects applied."""
        z = np.asarray(z, dtype=float)
        tu, al, wu, wl = z[I_TU], z[I_AL], z[I_WU], z[I_WL]
        zero = np.zeros_like(tu)
        ru, rl, _, _ = self.composition.measure(tu, tu + al, zero, zero, self.vector, wu, wl)
        return ru, rl

    def reading_jacobian(self, z: np.ndarray, h: float = 1e-6) -> np.ndarray:
        """d(readings)/dz (n, 2, nz) at states z (central differences in theta_u, omega_u, alpha, omega_l)."""
        z = np.asarray(z, dtype=float)
        n = z.shape[1]
        H = np.zeros((n, 2, self.nz))
        if not self.composition.has_measurement:
            H[:, 0, I_TU] = 1.0
            H[:, 1, I_TU] = H[:, 1, I_AL] = 1.0
            return H
        for c in (I_TU, I_WU, I_AL, I_WL):
            zp, zm = z.copy(), z.copy()
            zp[c] += h
            zm[c] -= h
            H[:, :, c] = ((np.stack(self.readings(zp)) - np.stack(self.readings(zm))) / (2 * h)).T
        return H
