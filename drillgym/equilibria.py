"""Equilibria of the rig for a constant voltage, their linearisation and stability.

Two kinds of equilibria (report 4.1.1, 4.2, 4.3.1; MODEL.md):

* **stick set** (``omega_u = omega_l = 0``): both discs at rest, the friction
  torques inside their stick sets.  With Tfu = km u + k_theta alpha and
  Tfl = -k_theta alpha this is an interval of windings alpha, non-empty only
  for ``u_lo <= u <= u_hi``; for u > 0 the bound is
  ``us = (Tcu + dTcu + Ts) / km`` (R4, 0.1509 V with the brake), below which
  the stick set is globally stable.
* **slip equilibria** (``omega_u = omega_l = omega != 0``): the discs turn
  together.  Torsional: ``k_theta alpha = -Tfl(omega)``,
  ``km u = Tfu(omega) + Tfl(omega)``.  Lateral / coupled: a steady whirl, constant
  (x, y) in the frame that co-rotates with the upper disc, with
  ``(x, y) = e mr omega^2 / D [[k - m omega^2, b omega], [-b omega, k - m omega^2]] (cos alpha, sin alpha)``,
  ``D = (k - m omega^2)^2 + b^2 omega^2``, ``r = e mr omega^2 / sqrt(D)``, and
  ``km u = Tfu + Tfl + b r^2 omega``.  Parametrising the branch by omega and
  computing u(omega) gives the whole branch (several equilibria per voltage
  are found by root bracketing in omega).  With effects (``effects=``, a
  composition of :mod:`drillgym.effects`) the closed form of the base model is
  refined by Newton on the composition's compiled ``state_derivative`` residual,
  so the equilibria are those of the simulator, effects included; effects that
  make the rig depend on its angle or on time (no constant equilibria) are refused.

Linearisation (:func:`linearise`) is by central finite differences of the
core's compiled ``state_derivative`` in the slip modes of the equilibrium
(verified against the analytic torsional Jacobian in the tests).  It returns a
``control.StateSpace`` with named states, inputs and outputs:

==========  ==============================================  =========================
variant     states                                           outputs
==========  ==============================================  =========================
reduced     upper: (omega_u); torsional: (alpha, omega_u,    all states
            omega_l); lateral/coupled: (alpha, omega_u,
            omega_l, x, y, vx, vy) (x, y rotating frame)
angles      theta_u, theta_l instead of alpha (for           theta_u, theta_l (encoders);
            observers: the encoders measure the angles)      + r for lateral/coupled
==========  ==============================================  =========================

Input: ``u`` (V); the states of the composition's effects (e.g. ``u_m`` of
motor_lag) are appended.  A transport delay (Delay effect) is not part of the
finite-dimensional linearisation.  Units: rad, rad/s, m, m/s.  The linear model describes
deviations from the equilibrium (for the angle variant: from the uniformly
rotating equilibrium motion).

:func:`routh_hurwitz_torsional` gives the report's stability analysis of the
torsional slip equilibria: the critical linearised brake damping (R1), the
velocities where stability changes (R2), the Hopf voltages (R3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import control
import numpy as np
from scipy.optimize import brentq, fsolve

from .configurations import Configuration, parse_configuration
from .effects.base import Force, Measurement
from .effects.composition import Composition, compose
from .errors import FitError, InputError
from .params import ParameterError, RigParams

__all__ = [
    "RigModel",
    "as_model",
    "Equilibrium",
    "StickSet",
    "RouthHurwitz",
    "equilibrium_voltage",
    "slip_equilibrium",
    "slip_equilibria",
    "stick_set",
    "linearise",
    "eigenvalues",
    "routh_hurwitz_torsional",
    "lower_damping",
    "supported_configuration",
    "state_names",
]

FD_STEP = 1e-6  # relative central-difference step of the linearisation


class RigModel:
    """A rig model: base parameters, a composition of effects and the effects' values (picklable).

    Every function of this module and of :mod:`drillgym.bifurcation` takes one where it takes
    ``params``: ``RigModel(RigParams(), ["motor_lag"], {"tau_m": 0.02})``.

    Parameters
    ----------
    params : RigParams, optional
        Base parameters; default the identified set.
    effects : optional
        Effects (names, file specs, classes or instances, :mod:`drillgym.effects`).
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.
    """

    def __init__(self, params: RigParams | None = None, effects=None, effect_params=None) -> None:
        self.params = params or RigParams()
        self.comp, self.values = compose(effects, effect_params)
        self.p = self.comp.vector(self.params, self.values)
        self.model = self.comp.kernels.model
        self.n_state = self.comp.n_state
        self.dy = np.zeros(self.n_state)
        self.fric = np.zeros(2)
        #: the composition changes the equations (not only what the sensors read)
        self.dynamic_effects = any(not issubclass(e, Measurement) for e in self.comp.effects)
        self.has_forces = any(issubclass(e, Force) for e in self.comp.effects)

    def __reduce__(self):
        return (RigModel, (self.params, self.comp, self.values))

    @property
    def composition(self) -> Composition:
        """The composition of effects."""
        return self.comp

    def f(self, y: np.ndarray, mode: np.ndarray, u: float, cfg: Configuration, t: float = 0.0) -> np.ndarray:
        """The compiled right-hand side at (t, y) in the friction modes ``mode``."""
        self.model.state_derivative(t, y, mode, float(u), self.p, int(cfg), 0.0, self.dy, self.fric)
        return self.dy.copy()

    def zero_state(self) -> np.ndarray:
        """A zero state vector of the model's length (8 + the effects' states)."""
        return np.zeros(self.n_state)


_Rig = RigModel


def as_model(params: RigParams | RigModel | None = None, effects=None, effect_params=None) -> RigModel:
    """A RigModel from RigParams (+ effects), or a RigModel itself.

    Parameters
    ----------
    params : RigParams or RigModel, optional
        Base parameters (default the identified set) or a model, returned as it is.
    effects : optional
        Effects of a new model.
    effect_params : mapping of str to float, optional
        Their parameter values by name.

    Returns
    -------
    RigModel
        The model.
    """
    if isinstance(params, RigModel):
        return params
    return RigModel(params, effects, effect_params)


_rig_of = as_model


def supported_configuration(
    config: str | Configuration, params: RigParams | _Rig | None = None, effects=None, effect_params=None
) -> Configuration:
    """Parse ``config`` and check that equilibria are defined for it (else ValueError)."""
    cfg = parse_configuration(config)
    if cfg is Configuration.FREE_VIBRATION:
        raise InputError("equilibria are defined for upper, torsional, lateral and coupled, not free_vibration")
    return cfg


# --------------------------------------------------------------------- states
def state_names(
    config: str | Configuration,
    variant: str = "reduced",
    params: RigParams | _Rig | None = None,
    effects=None,
    effect_params=None,
) -> list[str]:
    """Names of the linearisation's states for ``config`` and ``variant`` ('reduced' or 'angles')."""
    cfg = parse_configuration(config)
    if variant not in ("reduced", "angles"):
        raise InputError(f"variant must be 'reduced' or 'angles', got {variant!r}")
    if cfg is Configuration.UPPER:
        names = ["omega_u"] if variant == "reduced" else ["theta_u", "omega_u"]
    else:
        names = (
            ["alpha", "omega_u", "omega_l"] if variant == "reduced" else ["theta_u", "theta_l", "omega_u", "omega_l"]
        )
        if cfg.lateral_free:
            names += ["x", "y", "vx", "vy"]
    rig = _rig_of(params, effects, effect_params) if (effects is not None or isinstance(params, _Rig)) else None
    if rig is not None:
        names += list(rig.comp.state_names)
    return names


_MECH_INDEX = {"theta_u": 0, "theta_l": 1, "omega_u": 2, "omega_l": 3, "x": 4, "y": 5, "vx": 6, "vy": 7}


def _index(name: str, comp: Composition) -> int:
    return _MECH_INDEX[name] if name in _MECH_INDEX else 8 + comp.state_index(name)


def _to_full(z: np.ndarray, names: Sequence[str], base: np.ndarray, comp: Composition) -> np.ndarray:
    y = base.copy()
    for v, n in zip(z, names):
        if n == "alpha":
            y[0] = 0.0
            y[1] = v
        else:
            y[_index(n, comp)] = v
    return y


def _from_full_derivative(dy: np.ndarray, names: Sequence[str], comp: Composition) -> np.ndarray:
    return np.array([dy[1] - dy[0] if n == "alpha" else dy[_index(n, comp)] for n in names])


# ------------------------------------------------------------------ equilibria
@dataclass(frozen=True)
class Equilibrium:
    """A slip equilibrium: both discs at speed ``omega`` (rad/s) under voltage ``u`` (V).

    ``alpha`` is the winding theta_l - theta_u (rad); ``x``, ``y`` the whirl
    position of the lower disc centre in the co-rotating frame (m; 0 when the
    disc is held); ``effect_states`` the equilibrium values of the effects' states.
    ``eigenvalues`` (1/s) are those of the reduced linearisation.
    """

    config: Configuration
    u: float
    omega: float
    alpha: float
    x: float = 0.0
    y: float = 0.0
    params: RigParams = field(default_factory=RigParams, repr=False, compare=False)
    eigenvalues: np.ndarray = field(default=None, repr=False, compare=False)
    effect_states: tuple = field(default=(), repr=False, compare=False)
    rig: _Rig | None = field(default=None, repr=False, compare=False)

    @property
    def r(self) -> float:
        """Radial whirl amplitude sqrt(x^2 + y^2) (m)."""
        return math.hypot(self.x, self.y)

    @property
    def modes(self) -> np.ndarray:
        """Friction modes (upper, lower) of the equilibrium: slipping in the direction of omega."""
        d = 1 if self.omega > 0 else -1
        return np.array([d, d if self.config is not Configuration.UPPER else 0], dtype=np.int64)

    @property
    def model(self) -> _Rig:
        """The RigModel of the equilibrium (its effects included)."""
        return self.rig if self.rig is not None else _Rig(self.params)

    @property
    def state(self) -> np.ndarray:
        """Full simulator state (theta_u = 0, theta_l = alpha; then the effects' states)."""
        y = np.zeros(8 + len(self.effect_states))
        y[1] = self.alpha if self.config is not Configuration.UPPER else 0.0
        y[2] = self.omega
        y[3] = self.omega if self.config is not Configuration.UPPER else 0.0
        y[4], y[5] = self.x, self.y
        y[8:] = self.effect_states
        return y

    @property
    def stable(self) -> bool:
        """Locally asymptotically stable (all eigenvalues in the open left half plane)."""
        return bool(np.max(self.eigenvalues.real) < 0.0)

    def to_dict(self) -> dict:
        """JSON-ready summary: kind, u (V), omega (rad/s), alpha (rad), x, y, r (m), stability."""
        return {
            "kind": "slip",
            "u": self.u,
            "omega": self.omega,
            "alpha": self.alpha,
            "x": self.x,
            "y": self.y,
            "r": self.r,
            "stable": self.stable,
            "max_real_eigenvalue": float(np.max(self.eigenvalues.real)),
        }


@dataclass(frozen=True)
class StickSet:
    """The stick equilibrium set at voltage ``u`` (V): both discs at rest, winding in [alpha_lo, alpha_hi] (rad)."""

    u: float
    alpha_lo: float
    alpha_hi: float

    def to_dict(self) -> dict:
        """JSON-ready summary: kind, u (V), omega = 0, alpha_lo, alpha_hi (rad), stable."""
        return {
            "kind": "stick",
            "u": self.u,
            "omega": 0.0,
            "alpha_lo": self.alpha_lo,
            "alpha_hi": self.alpha_hi,
            "stable": True,
        }


def _slip_torques(omega: float, rig: _Rig, cfg: Configuration) -> tuple[float, float]:
    d = 1.0 if omega > 0 else -1.0
    y = rig.zero_state()
    tfu = rig.model.upper_slip_torque(omega, d, 0.0, y, rig.p)
    tfl = 0.0 if cfg is Configuration.UPPER else rig.model.lower_slip_torque(omega, d, 0.0, y, rig.p, cfg.brake)
    return tfu, tfl


def _closed_form(cfg: Configuration, omega: float, rig: _Rig) -> tuple[float, float, float, float]:
    """(u, alpha, x, y) of the base model's slip equilibrium at speed omega (isotropic lateral constraints)."""
    params = rig.params
    tfu, tfl = _slip_torques(omega, rig, cfg)
    if cfg is Configuration.UPPER:
        return tfu / params.km, 0.0, 0.0, 0.0
    if not cfg.lateral_free:
        return (tfu + tfl) / params.km, -tfl / params.ktheta, 0.0, 0.0
    P = params.e * params.mr
    W = omega
    kk = params.k - params.m * W * W
    D = kk * kk + (params.b * W) ** 2
    r2 = P * P * W**4 / D
    alpha = -(tfl + P * P * params.b * W**5 / D) / params.ktheta
    c, s = math.cos(alpha), math.sin(alpha)
    x = P * W * W / D * (kk * c + params.b * W * s)
    y = P * W * W / D * (-params.b * W * c + kk * s)
    u = (tfu + tfl + params.b * r2 * W) / params.km
    return u, alpha, x, y


def _refine(cfg: Configuration, omega: float, guess: tuple, rig: _Rig) -> tuple[float, float, float, float, tuple]:
    """Newton (fsolve) on the composition's residual: unknowns u, alpha (x, y when the disc moves
    laterally) and the effects' states; residual: the accelerations and the effects' state rates."""
    lateral = cfg.lateral_free
    ns = rig.comp.n_states
    mode = np.array([1 if omega > 0 else -1] * 2, dtype=np.int64)
    if cfg is Configuration.UPPER:
        mode[1] = 0
    scale = np.array([1.0, 1.0] + ([1e-3, 1e-3] if lateral else []) + [1.0] * ns)

    def state(v: np.ndarray, shift: float = 0.0) -> tuple[float, np.ndarray]:
        z = v * scale
        u, alpha = z[0], z[1]
        st = rig.zero_state()
        st[0] = shift
        st[1] = shift + (alpha if cfg is not Configuration.UPPER else 0.0)
        st[2] = omega
        st[3] = omega if cfg is not Configuration.UPPER else 0.0
        if lateral:
            st[4], st[5] = z[2], z[3]
        st[8:] = z[2 + 2 * lateral :]
        return u, st

    def residual(v: np.ndarray, shift: float = 0.0, t: float = 0.0) -> np.ndarray:
        u, st = state(v, shift)
        dy = rig.f(st, mode, u, cfg, t)
        out = [dy[2], dy[3] if cfg is not Configuration.UPPER else st[1]]
        if lateral:
            out += [dy[6], dy[7]]
        out += list(dy[8:])
        return np.array(out)

    u0, a0, x0, y0 = guess
    z0 = [u0, a0] + ([x0, y0] if lateral else []) + [u0] * ns  # effect states start at the voltage (lags)
    sol, _, ier, msg = fsolve(residual, np.asarray(z0) / scale, full_output=True, xtol=1e-13)
    res = residual(sol)
    if np.max(np.abs(res)) > 1e-8:
        raise FitError(
            f"slip equilibrium at omega={omega} rad/s of the model {rig.comp.label!r} did not converge: {msg}"
        )
    moved = np.max(np.abs(residual(sol, shift=1.2345, t=7.5)))
    if moved > 1e-6:
        raise ParameterError(
            f"the model {rig.comp.label!r} has no constant equilibria: its effects depend on the "
            f"disc angles or on time (residual {moved:.2g} after a rotation); remove those effects"
        )
    u, st = state(sol)
    return float(u), float(st[1] - st[0]), float(st[4]), float(st[5]), tuple(float(v) for v in st[8:])


def slip_equilibrium(
    config: str | Configuration,
    omega: float,
    params: RigParams | _Rig | None = None,
    *,
    with_eigenvalues: bool = True,
    effects=None,
    effect_params=None,
) -> Equilibrium:
    """The slip equilibrium whose discs turn at ``omega``, and the voltage that holds it.

    Closed form for the base model; with effects refined by Newton on the simulator's residual.

    Parameters
    ----------
    config : str or Configuration
        Rig configuration: ``"upper"``, ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    omega : float
        Speed of both discs (rad/s), not 0.
    params : RigParams, optional
        Base parameters; default the identified set.
    with_eigenvalues : bool, optional
        Also compute the eigenvalues of the reduced linearisation (``Equilibrium.eigenvalues``, 1/s).
    effects : optional
        Effects of the model (names, file specs, classes or instances, :mod:`drillgym.effects`); effects
        that make the rig depend on its angle or on time are refused.
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.

    Returns
    -------
    Equilibrium
        Voltage ``u`` (V), speed ``omega`` (rad/s), winding ``alpha`` (rad), whirl position ``x``, ``y``
        (m, co-rotating frame), the effects' states and the eigenvalues.
    """
    rig = _rig_of(params, effects, effect_params)
    cfg = supported_configuration(config)
    if not (np.isfinite(omega) and omega != 0.0):
        raise InputError(f"omega must be a finite non-zero speed for a slip equilibrium, got {omega!r}")
    u, alpha, x, y = _closed_form(cfg, float(omega), rig)
    states: tuple = ()
    if rig.dynamic_effects:
        u, alpha, x, y, states = _refine(cfg, float(omega), (u, alpha, x, y), rig)
    elif rig.comp.n_states:
        states = (float(u),) * rig.comp.n_states
    eq = Equilibrium(cfg, float(u), float(omega), float(alpha), float(x), float(y), rig.params, None, states, rig)
    if with_eigenvalues:
        eq = Equilibrium(cfg, eq.u, eq.omega, eq.alpha, eq.x, eq.y, rig.params, eigenvalues(eq), states, rig)
    return eq


def equilibrium_voltage(
    config: str | Configuration,
    omega: float | np.ndarray,
    params: RigParams | _Rig | None = None,
    effects=None,
    effect_params=None,
) -> np.ndarray:
    """The constant voltage that holds the slip equilibrium at speed ``omega``.

    Parameters
    ----------
    config : str or Configuration
        Rig configuration: ``"upper"``, ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    omega : float or ndarray
        Speed(s) of both discs (rad/s), not 0.
    params : RigParams, optional
        Base parameters; default the identified set.
    effects : optional
        Effects of the model (names, file specs, classes or instances, :mod:`drillgym.effects`); effects
        that make the rig depend on its angle or on time are refused.
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.

    Returns
    -------
    ndarray
        u(omega) (V), shaped as ``omega``.
    """
    rig = _rig_of(params, effects, effect_params)
    cfg = supported_configuration(config)
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    if rig.dynamic_effects:
        out = np.array([slip_equilibrium(cfg, float(v), rig, with_eigenvalues=False).u for v in w])
    else:
        out = np.array([_closed_form(cfg, float(v), rig)[0] for v in w])
    return out if np.ndim(omega) else out[0]


def slip_equilibria(
    config: str | Configuration,
    u: float,
    params: RigParams | _Rig | None = None,
    omega_max: float = 200.0,
    n_grid: int = 400,
    effects=None,
    effect_params=None,
) -> list[Equilibrium]:
    """All slip equilibria at voltage ``u`` with 0 < |omega| <= omega_max, sorted by speed.

    Roots of u(omega) = u are bracketed on a geometric grid of omega (in the
    direction of u) and located with Brent's method.

    Parameters
    ----------
    config : str or Configuration
        Rig configuration: ``"upper"``, ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    u : float
        Constant motor voltage (V).
    params : RigParams, optional
        Base parameters; default the identified set.
    omega_max : float, optional
        Largest speed searched (rad/s).  Default 200.
    n_grid : int, optional
        Points of the bracketing grid.  Default 400.
    effects : optional
        Effects of the model (names, file specs, classes or instances, :mod:`drillgym.effects`); effects
        that make the rig depend on its angle or on time are refused.
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.

    Returns
    -------
    list of Equilibrium
        The slip equilibria, sorted by speed (empty when there is none).
    """
    rig = _rig_of(params, effects, effect_params)
    cfg = supported_configuration(config)
    if not np.isfinite(u):
        raise InputError(f"voltage must be finite, got {u!r}")
    if u == 0.0:
        return []
    d = 1.0 if u > 0 else -1.0
    grid = d * np.geomspace(1e-7, omega_max, n_grid)
    g = equilibrium_voltage(cfg, grid, rig) - u
    out = []
    for i in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) <= 0):
        if g[i] == 0.0 and i > 0 and g[i - 1] == 0.0:
            continue
        w = brentq(lambda v: equilibrium_voltage(cfg, v, rig) - u, grid[i], grid[i + 1], xtol=1e-13, rtol=1e-14)
        out.append(slip_equilibrium(cfg, w, rig))
    return sorted(out, key=lambda e: abs(e.omega))


def stick_set(
    config: str | Configuration, u: float, params: RigParams | _Rig | None = None, effects=None, effect_params=None
) -> StickSet | None:
    """The stick equilibrium set at voltage ``u``, or None when the discs cannot rest (|u| too large).

    Both discs at rest: the holding torques (upper: km u + string torque, lower: -string torque)
    must lie in the stick sets.  Closed form for a linear string; with Force effects the set of
    windings is found on the composition's own holding torques (bisection of its ends).

    Parameters
    ----------
    config : str or Configuration
        Rig configuration: ``"upper"``, ``"torsional"``, ``"lateral"`` or ``"coupled"``.
    u : float
        Constant motor voltage (V).
    params : RigParams, optional
        Base parameters; default the identified set.
    effects : optional
        Effects of the model (names, file specs, classes or instances, :mod:`drillgym.effects`); effects
        that make the rig depend on its angle or on time are refused.
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.

    Returns
    -------
    StickSet or None
        The windings [alpha_lo, alpha_hi] (rad) at which both discs rest, or None.
    """
    rig = _rig_of(params, effects, effect_params)
    cfg = supported_configuration(config)
    params = rig.params
    y0 = rig.zero_state()
    lo_u, hi_u = rig.model.upper_stick_bounds(0.0, y0, rig.p)
    if cfg is Configuration.UPPER:
        return StickSet(float(u), 0.0, 0.0) if lo_u <= params.km * u <= hi_u else None
    lo_l, hi_l = rig.model.lower_stick_bounds(0.0, y0, rig.p, cfg.brake)
    kt = params.ktheta
    a_lo = max(-hi_l / kt, (lo_u - params.km * u) / kt)
    a_hi = min(-lo_l / kt, (hi_u - params.km * u) / kt)
    if not rig.dynamic_effects:
        return StickSet(float(u), float(a_lo), float(a_hi)) if a_lo <= a_hi else None
    return _stick_set_numeric(cfg, float(u), rig, (a_lo + a_hi) / 2)


def _stick_set_numeric(cfg: Configuration, u: float, rig: _Rig, centre: float) -> StickSet | None:
    mode = np.zeros(2, dtype=np.int64)
    n = rig.comp.n_states

    def margin(alpha: float) -> float:
        st = rig.zero_state()
        st[1] = alpha
        st[8:] = u  # the effects' states at rest (a lag has settled at the voltage)
        rig.f(st, mode, u, cfg)
        fu, fl = rig.fric
        lo_u, hi_u = rig.model.upper_stick_bounds(0.0, st, rig.p)
        lo_l, hi_l = rig.model.lower_stick_bounds(0.0, st, rig.p, cfg.brake)
        return min(hi_u - fu, fu - lo_u, hi_l - fl, fl - lo_l)

    del n
    grid = centre + np.linspace(-40.0, 40.0, 8001)
    m = np.array([margin(a) for a in grid])
    ok = m >= 0
    if not ok.any():
        return None
    k = int(np.argmax(m))
    i0, i1 = k, k
    while i0 > 0 and ok[i0 - 1]:
        i0 -= 1
    while i1 < len(grid) - 1 and ok[i1 + 1]:
        i1 += 1
    lo = brentq(margin, grid[i0 - 1], grid[i0], xtol=1e-12) if i0 > 0 else grid[0]
    hi = brentq(margin, grid[i1], grid[i1 + 1], xtol=1e-12) if i1 < len(grid) - 1 else grid[-1]
    return StickSet(u, float(lo), float(hi))


# -------------------------------------------------------------- linearisation
def linearise(eq: Equilibrium, variant: str = "reduced", rel_step: float = FD_STEP) -> control.StateSpace:
    """Linearisation about a slip equilibrium as a ``control.StateSpace``.

    Central finite differences of the composition's ``state_derivative`` in the
    equilibrium's slip modes, step ``rel_step`` relative to each state's scale.

    Parameters
    ----------
    eq : Equilibrium
        A slip equilibrium (:func:`slip_equilibrium`, :func:`slip_equilibria`).
    variant : str, optional
        ``"reduced"`` (default): states (alpha, omega_u, omega_l), plus (x, y, vx, vy) in the rotating
        frame for lateral/coupled (upper: omega_u only), outputs all states.  ``"angles"``: theta_u,
        theta_l instead of alpha, outputs the encoder angles (and r for lateral/coupled).
    rel_step : float, optional
        Finite-difference step relative to each state's scale.

    Returns
    -------
    control.StateSpace
        Named states, input ``u`` (V) and outputs; the effects' states are appended.  Units: rad,
        rad/s, m, m/s.  It describes deviations from the equilibrium.
    """
    cfg = eq.config
    rig = eq.model
    comp = rig.comp
    names = state_names(cfg, variant, rig)
    base = eq.state
    z0 = np.array([eq.alpha if n == "alpha" else base[_index(n, comp)] for n in names])
    scale = np.array([1e-3 if n in ("x", "y", "vx", "vy") else 1.0 for n in names])
    mode = eq.modes
    n = len(names)
    A = np.zeros((n, n))

    def f(y: np.ndarray, u: float) -> np.ndarray:
        return _from_full_derivative(rig.f(y, mode, u, cfg), names, comp)

    for j in range(n):
        h = rel_step * scale[j]
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        A[:, j] = (f(_to_full(zp, names, base, comp), eq.u) - f(_to_full(zm, names, base, comp), eq.u)) / (2 * h)
    hu = rel_step
    yb = _to_full(z0, names, base, comp)
    Bm = ((f(yb, eq.u + hu) - f(yb, eq.u - hu)) / (2 * hu))[:, None]
    if variant == "reduced":
        outs = list(names)
        C = np.eye(n)
    else:
        outs = [o for o in ("theta_u", "theta_l") if o in names]
        C = np.array([[1.0 if s == o else 0.0 for s in names] for o in outs])
        if cfg.lateral_free:
            outs.append("r")
            row = np.zeros(n)
            if eq.r > 0:
                row[names.index("x")] = eq.x / eq.r
                row[names.index("y")] = eq.y / eq.r
            C = np.vstack([C, row])
    D = np.zeros((C.shape[0], 1))
    return control.ss(A, Bm, C, D, states=names, inputs=["u"], outputs=outs)


def eigenvalues(eq: Equilibrium) -> np.ndarray:
    """Eigenvalues (1/s) of the reduced linearisation, sorted by decreasing real part."""
    lam = np.linalg.eigvals(linearise(eq).A)
    return lam[np.argsort(-lam.real)]


def lower_damping(
    omega: float | np.ndarray,
    params: RigParams | _Rig | None = None,
    brake: bool = True,
    effects=None,
    effect_params=None,
) -> np.ndarray:
    """Linearised lower friction damping dl = dTfl/domega at omega != 0 (central differences).

    Parameters
    ----------
    omega : float or ndarray
        Lower-disc speed(s) (rad/s), not 0.
    params : RigParams, optional
        Base parameters; default the identified set.
    brake : bool, optional
        The brake's Stribeck law (True, default) or the bearing friction (False).
    effects : optional
        Effects of the model (:mod:`drillgym.effects`).
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.

    Returns
    -------
    ndarray
        dl (N m s/rad), shaped as ``omega``; negative where the friction law falls with speed.
    """
    rig = _rig_of(params, effects, effect_params)
    y = rig.zero_state()
    slip = rig.model.lower_slip_torque
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    h = 1e-6 * np.maximum(np.abs(w), 1e-3)
    d = np.sign(w)  # float directions (+1.0/-1.0): the kernels take them as floats
    out = np.array(
        [
            (slip(v + hv, dv, 0.0, y, rig.p, brake) - slip(v - hv, dv, 0.0, y, rig.p, brake)) / (2 * hv)
            for v, hv, dv in zip(w, h, d)
        ]
    )
    return out if np.ndim(omega) else out[0]


# ------------------------------------------------------------- Routh-Hurwitz
@dataclass(frozen=True)
class RouthHurwitz:
    """Routh-Hurwitz analysis of the torsional slip equilibria (omega > 0).

    The characteristic polynomial of the reduced linearisation (alpha, omega_u,
    omega_l) is s^3 + a2 s^2 + a1 s + a0 with a2 = du/Ju + dl/Jl,
    a1 = du dl/(Ju Jl) + k/Ju + k/Jl, a0 = k (du + dl)/(Ju Jl), du = bu + dbu.
    Stable iff a2 > 0, a0 > 0, a2 a1 > a0; the last one fails first, at the
    critical damping ``dl_critical`` (N m s/rad, R1).  ``omega_critical``
    (rad/s, R2) are the speeds where dl(omega) crosses it and ``u_hopf`` (V, R3)
    the voltages of those equilibria.
    """

    dl_critical: float
    omega_critical: tuple[float, ...]
    u_hopf: tuple[float, ...]

    @staticmethod
    def coefficients(dl: float, params: RigParams) -> tuple[float, float, float]:
        """(a2, a1, a0) of the characteristic polynomial for a linearised lower damping dl."""
        Ju, Jl, k = params.Ju, params.Jl, params.ktheta
        du = params.bu + params.dbu
        return du / Ju + dl / Jl, du * dl / (Ju * Jl) + k / Ju + k / Jl, k * (du + dl) / (Ju * Jl)


def routh_hurwitz_torsional(params: RigParams | None = None, omega_max: float = 50.0) -> RouthHurwitz:
    """Critical damping, critical speeds and Hopf voltages of the torsional configuration (R1-R3).

    Parameters
    ----------
    params : RigParams, optional
        Base parameters; default the identified set.
    omega_max : float, optional
        Largest speed searched for stability changes (rad/s).  Default 50.

    Returns
    -------
    RouthHurwitz
        ``dl_critical`` (N m s/rad), ``omega_critical`` (rad/s) and ``u_hopf`` (V).
    """
    params = params or RigParams()

    def margin(dl: float) -> float:
        a2, a1, a0 = RouthHurwitz.coefficients(dl, params)
        return a2 * a1 - a0

    du = params.bu + params.dbu
    dl_c = brentq(margin, -min(du, params.Jl * du / params.Ju) * (1 - 1e-9), 0.0, xtol=1e-15)
    grid = np.geomspace(1e-4, omega_max, 2000)
    g = lower_damping(grid, params) - dl_c
    roots = tuple(
        brentq(lambda w: lower_damping(w, params) - dl_c, grid[i], grid[i + 1], xtol=1e-14)
        for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:]))
    )
    u_h = tuple(float(equilibrium_voltage(Configuration.TORSIONAL, w, params)) for w in roots)
    return RouthHurwitz(float(dl_c), tuple(float(w) for w in roots), u_h)
