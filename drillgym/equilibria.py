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
  are found by root bracketing in omega).  The closed form is refined by Newton
  on the core's own :func:`drillgym.dynamics.state_derivative` residual, so the
  equilibria are those of the simulator, extension effects included.

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

Input: ``u`` (V); with the motor_lag effect on (``tau_m > 0``) the state
``u_m`` is appended.  Units: rad, rad/s, m, m/s.  The linear model describes
deviations from the equilibrium (for the angle variant: from the uniformly
rotating equilibrium motion).

:func:`routh_hurwitz_torsional` gives the report's stability analysis of the
torsional slip equilibria: the critical linearised brake damping (R1), the
velocities where stability changes (R2), the Hopf voltages (R3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import control
import numpy as np
from scipy.optimize import brentq, fsolve

from .configurations import N_STATE, Configuration, parse_configuration
from .dynamics import state_derivative
from .friction import lower_slip_torque, lower_stick_bounds, upper_slip_torque, upper_stick_bounds
from .params import ParameterError, RigParams

__all__ = [
    "Equilibrium", "StickSet", "RouthHurwitz", "equilibrium_voltage", "slip_equilibrium", "slip_equilibria",
    "stick_set", "linearise", "eigenvalues", "routh_hurwitz_torsional", "lower_damping", "supported_configuration",
    "state_names",
]

FD_STEP = 1e-6  # relative central-difference step of the linearisation
_NO_EQUILIBRIUM_EFFECTS = ("pf_a1", "pf_a2", "drift", "dk", "db")


def supported_configuration(config: "str | Configuration", params: RigParams | None = None) -> Configuration:
    """Parse ``config`` and check that constant equilibria exist (else ValueError/ParameterError)."""
    cfg = parse_configuration(config)
    if cfg is Configuration.FREE_VIBRATION:
        raise ValueError("equilibria are defined for upper, torsional, lateral and coupled, not free_vibration")
    p = params or RigParams()
    for name in _NO_EQUILIBRIUM_EFFECTS:
        if getattr(p, name) != 0.0:
            raise ParameterError(f"parameter {name}={getattr(p, name)!r}: with this effect on the rig has no "
                                 "constant equilibria (position/time dependent or anisotropic); set it to 0")
    return cfg


# --------------------------------------------------------------------- states
def state_names(config: "str | Configuration", variant: str = "reduced", params: RigParams | None = None) -> list[str]:
    """Names of the linearisation's states for ``config`` and ``variant`` ('reduced' or 'angles')."""
    cfg = parse_configuration(config)
    if variant not in ("reduced", "angles"):
        raise ValueError(f"variant must be 'reduced' or 'angles', got {variant!r}")
    if cfg is Configuration.UPPER:
        names = ["omega_u"] if variant == "reduced" else ["theta_u", "omega_u"]
    else:
        names = ["alpha", "omega_u", "omega_l"] if variant == "reduced" else ["theta_u", "theta_l", "omega_u", "omega_l"]
        if cfg.lateral_free:
            names += ["x", "y", "vx", "vy"]
    if params is not None and params.tau_m > 0:
        names.append("u_m")
    return names


_FULL_INDEX = {"theta_u": 0, "theta_l": 1, "omega_u": 2, "omega_l": 3, "x": 4, "y": 5, "vx": 6, "vy": 7, "u_m": 8}


def _to_full(z: np.ndarray, names: Sequence[str], base: np.ndarray) -> np.ndarray:
    y = base.copy()
    for v, n in zip(z, names):
        if n == "alpha":
            y[0] = 0.0
            y[1] = v
        else:
            y[_FULL_INDEX[n]] = v
    return y


def _from_full_derivative(dy: np.ndarray, names: Sequence[str]) -> np.ndarray:
    return np.array([dy[1] - dy[0] if n == "alpha" else dy[_FULL_INDEX[n]] for n in names])


# ------------------------------------------------------------------ equilibria
@dataclass(frozen=True)
class Equilibrium:
    """A slip equilibrium: both discs at speed ``omega`` (rad/s) under voltage ``u`` (V).

    ``alpha`` is the winding theta_l - theta_u (rad); ``x``, ``y`` the whirl
    position of the lower disc centre in the co-rotating frame (m; 0 when the
    disc is held).  ``eigenvalues`` (1/s) are those of the reduced linearisation.
    """

    config: Configuration
    u: float
    omega: float
    alpha: float
    x: float = 0.0
    y: float = 0.0
    params: RigParams = field(default_factory=RigParams, repr=False, compare=False)
    eigenvalues: np.ndarray = field(default=None, repr=False, compare=False)

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
    def state(self) -> np.ndarray:
        """Full simulator state (theta_u = 0, theta_l = alpha), see :mod:`drillgym.configurations`."""
        y = np.zeros(N_STATE)
        y[1] = self.alpha if self.config is not Configuration.UPPER else 0.0
        y[2] = self.omega
        y[3] = self.omega if self.config is not Configuration.UPPER else 0.0
        y[4], y[5] = self.x, self.y
        y[8] = self.u
        return y

    @property
    def stable(self) -> bool:
        """Locally asymptotically stable (all eigenvalues in the open left half plane)."""
        return bool(np.max(self.eigenvalues.real) < 0.0)

    def to_dict(self) -> dict:
        return {"kind": "slip", "u": self.u, "omega": self.omega, "alpha": self.alpha, "x": self.x, "y": self.y,
                "r": self.r, "stable": self.stable,
                "max_real_eigenvalue": float(np.max(self.eigenvalues.real))}


@dataclass(frozen=True)
class StickSet:
    """The stick equilibrium set at voltage ``u`` (V): both discs at rest, winding in [alpha_lo, alpha_hi] (rad)."""

    u: float
    alpha_lo: float
    alpha_hi: float

    def to_dict(self) -> dict:
        return {"kind": "stick", "u": self.u, "omega": 0.0, "alpha_lo": self.alpha_lo, "alpha_hi": self.alpha_hi,
                "stable": True}


def _pvec(params: RigParams | None) -> tuple[RigParams, np.ndarray]:
    p = params or RigParams()
    return p, p.to_vector()


def _slip_torques(omega: float, p: np.ndarray, cfg: Configuration) -> tuple[float, float]:
    d = 1 if omega > 0 else -1
    tfu = upper_slip_torque(omega, d, p)
    tfl = 0.0 if cfg is Configuration.UPPER else lower_slip_torque(omega, d, 0.0, 0.0, p, cfg.brake)
    return tfu, tfl


def _closed_form(cfg: Configuration, omega: float, params: RigParams, p: np.ndarray) -> tuple[float, float, float, float]:
    """(u, alpha, x, y) of the slip equilibrium at speed omega, closed form (isotropic lateral constraints)."""
    tfu, tfl = _slip_torques(omega, p, cfg)
    if cfg is Configuration.UPPER:
        return tfu / params.km, 0.0, 0.0, 0.0
    if not cfg.lateral_free:
        return (tfu + tfl) / params.km, -tfl / params.ktheta, 0.0, 0.0
    P = params.e * params.mr
    W = omega
    kk = params.k - params.m * W * W
    D = kk * kk + (params.b * W) ** 2
    r2 = P * P * W ** 4 / D
    alpha = -(tfl + P * P * params.b * W ** 5 / D) / params.ktheta
    c, s = math.cos(alpha), math.sin(alpha)
    x = P * W * W / D * (kk * c + params.b * W * s)
    y = P * W * W / D * (-params.b * W * c + kk * s)
    u = (tfu + tfl + params.b * r2 * W) / params.km
    return u, alpha, x, y


class _Work:
    """Work arrays for calling the compiled state_derivative from Python."""

    def __init__(self) -> None:
        self.dy = np.zeros(N_STATE)
        self.fric = np.zeros(2)

    def f(self, y: np.ndarray, mode: np.ndarray, u: float, p: np.ndarray, cfg: Configuration) -> np.ndarray:
        state_derivative(0.0, y, mode, float(u), p, int(cfg), 0.0, self.dy, self.fric)
        return self.dy.copy()


def slip_equilibrium(config: "str | Configuration", omega: float, params: RigParams | None = None,
                     *, with_eigenvalues: bool = True) -> Equilibrium:
    """The slip equilibrium whose discs turn at ``omega`` (rad/s, != 0), and the voltage that holds it.

    Closed form; with lateral dry friction (``Fc_lat > 0``) refined by Newton
    on the simulator's residual.
    """
    params, p = _pvec(params)
    cfg = supported_configuration(config, params)
    if not (np.isfinite(omega) and omega != 0.0):
        raise ValueError(f"omega must be a finite non-zero speed for a slip equilibrium, got {omega!r}")
    u, alpha, x, y = _closed_form(cfg, float(omega), params, p)
    if cfg.lateral_free and params.Fc_lat > 0:
        u, alpha, x, y = _refine_whirl(cfg, float(omega), (u, alpha, x, y), p)
    eq = Equilibrium(cfg, float(u), float(omega), float(alpha), float(x), float(y), params)
    if with_eigenvalues:
        eq = Equilibrium(cfg, eq.u, eq.omega, eq.alpha, eq.x, eq.y, params, eigenvalues(eq))
    return eq


def _refine_whirl(cfg: Configuration, omega: float, guess: tuple, p: np.ndarray) -> tuple:
    work = _Work()
    d = 1 if omega > 0 else -1
    mode = np.array([d, d], dtype=np.int64)
    scale = np.array([1.0, 1.0, 1e-3, 1e-3])

    def residual(v: np.ndarray) -> np.ndarray:
        u, alpha, x, y = v * scale
        st = np.array([0.0, alpha, omega, omega, x, y, 0.0, 0.0, u])
        dy = work.f(st, mode, u, p, cfg)
        return np.array([dy[2], dy[3], dy[6], dy[7]])

    sol, info, ier, _ = fsolve(residual, np.asarray(guess) / scale, full_output=True, xtol=1e-13)
    if ier != 1 and np.max(np.abs(residual(sol))) > 1e-9:
        raise RuntimeError(f"steady whirl at omega={omega} rad/s did not converge: {_}")
    return tuple(sol * scale)


def equilibrium_voltage(config: "str | Configuration", omega: "float | np.ndarray",
                        params: RigParams | None = None) -> np.ndarray:
    """u(omega) (V): the constant voltage that holds the slip equilibrium at speed omega (rad/s)."""
    params, p = _pvec(params)
    cfg = supported_configuration(config, params)
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    if cfg.lateral_free and params.Fc_lat > 0:
        out = np.array([slip_equilibrium(cfg, float(v), params, with_eigenvalues=False).u for v in w])
    else:
        out = np.array([_closed_form(cfg, float(v), params, p)[0] for v in w])
    return out if np.ndim(omega) else out[0]


def slip_equilibria(config: "str | Configuration", u: float, params: RigParams | None = None,
                    omega_max: float = 200.0, n_grid: int = 400) -> list[Equilibrium]:
    """All slip equilibria at voltage ``u`` (V) with 0 < |omega| <= omega_max, sorted by speed.

    Roots of u(omega) = u are bracketed on a geometric grid of omega (in the
    direction of u) and located with Brent's method.
    """
    params, _ = _pvec(params)
    cfg = supported_configuration(config, params)
    if not np.isfinite(u):
        raise ValueError(f"voltage must be finite, got {u!r}")
    if u == 0.0:
        return []
    d = 1.0 if u > 0 else -1.0
    grid = d * np.geomspace(1e-7, omega_max, n_grid)
    g = equilibrium_voltage(cfg, grid, params) - u
    out = []
    for i in np.flatnonzero(np.sign(g[:-1]) * np.sign(g[1:]) <= 0):
        if g[i] == 0.0 and i > 0 and g[i - 1] == 0.0:
            continue
        w = brentq(lambda v: equilibrium_voltage(cfg, v, params) - u, grid[i], grid[i + 1], xtol=1e-13, rtol=1e-14)
        out.append(slip_equilibrium(cfg, w, params))
    return sorted(out, key=lambda e: abs(e.omega))


def stick_set(config: "str | Configuration", u: float, params: RigParams | None = None) -> StickSet | None:
    """The stick equilibrium set at voltage u (V), or None when the discs cannot rest (|u| too large).

    Both discs at rest: Tfu = km u + k_theta alpha must lie in the upper stick
    set and Tfl = -k_theta alpha in the lower one (brake or bearing).
    """
    params, p = _pvec(params)
    cfg = supported_configuration(config, params)
    lo_u, hi_u = upper_stick_bounds(p)
    if cfg is Configuration.UPPER:
        return StickSet(float(u), 0.0, 0.0) if lo_u <= params.km * u <= hi_u else None
    lo_l, hi_l = lower_stick_bounds(0.0, 0.0, p, cfg.brake)
    kt = params.ktheta
    a_lo = max(-hi_l / kt, (lo_u - params.km * u) / kt)
    a_hi = min(-lo_l / kt, (hi_u - params.km * u) / kt)
    return StickSet(float(u), float(a_lo), float(a_hi)) if a_lo <= a_hi else None


# -------------------------------------------------------------- linearisation
def linearise(eq: Equilibrium, variant: str = "reduced", rel_step: float = FD_STEP) -> control.StateSpace:
    """Linearisation about a slip equilibrium as a ``control.StateSpace`` (see the module doc for states).

    Central finite differences of the core's ``state_derivative`` in the
    equilibrium's slip modes, step ``rel_step`` relative to each state's scale.
    """
    cfg = eq.config
    params, p = _pvec(eq.params)
    names = state_names(cfg, variant, params)
    base = eq.state
    z0 = np.array([eq.alpha if n == "alpha" else base[_FULL_INDEX[n]] for n in names])
    scale = np.array([1e-3 if n in ("x", "y", "vx", "vy") else 1.0 for n in names])
    work = _Work()
    mode = eq.modes
    n = len(names)
    A = np.zeros((n, n))
    for j in range(n):
        h = rel_step * scale[j]
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        fp = _from_full_derivative(work.f(_to_full(zp, names, base), mode, eq.u, p, cfg), names)
        fm = _from_full_derivative(work.f(_to_full(zm, names, base), mode, eq.u, p, cfg), names)
        A[:, j] = (fp - fm) / (2 * h)
    hu = rel_step
    yb = _to_full(z0, names, base)
    Bm = ((_from_full_derivative(work.f(yb, mode, eq.u + hu, p, cfg), names)
           - _from_full_derivative(work.f(yb, mode, eq.u - hu, p, cfg), names)) / (2 * hu))[:, None]
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


# ------------------------------------------------------------- Routh-Hurwitz
def lower_damping(omega: "float | np.ndarray", params: RigParams | None = None, brake: bool = True) -> np.ndarray:
    """Linearised lower friction damping dl = dTfl/domega (N m s/rad) at omega != 0 (central differences)."""
    _, p = _pvec(params)
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    h = 1e-6 * np.maximum(np.abs(w), 1e-3)
    d = np.sign(w).astype(int)
    out = np.array([(lower_slip_torque(v + hv, dv, 0.0, 0.0, p, brake) - lower_slip_torque(v - hv, dv, 0.0, 0.0, p, brake))
                    / (2 * hv) for v, hv, dv in zip(w, h, d)])
    return out if np.ndim(omega) else out[0]


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
    """Critical damping, critical speeds and Hopf voltages of the torsional configuration (R1-R3)."""
    params = params or RigParams()

    def margin(dl: float) -> float:
        a2, a1, a0 = RouthHurwitz.coefficients(dl, params)
        return a2 * a1 - a0

    du = params.bu + params.dbu
    dl_c = brentq(margin, -min(du, params.Jl * du / params.Ju) * (1 - 1e-9), 0.0, xtol=1e-15)
    grid = np.geomspace(1e-4, omega_max, 2000)
    g = lower_damping(grid, params) - dl_c
    roots = tuple(brentq(lambda w: lower_damping(w, params) - dl_c, grid[i], grid[i + 1], xtol=1e-14)
                  for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])))
    u_h = tuple(float(equilibrium_voltage(Configuration.TORSIONAL, w, params)) for w in roots)
    return RouthHurwitz(float(dl_c), tuple(float(w) for w in roots), u_h)
