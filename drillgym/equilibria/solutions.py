"""The equilibria for a constant voltage: slip equilibria (closed form, refined with effects) and the stick set."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq, fsolve

from ..configurations import Configuration
from ..errors import FitError, InputError
from ..params import ParameterError, RigParams
from ..run_setup import real_number, real_numbers
from .linear import eigenvalues
from .model import (
    Equilibrium,
    RigModel,
    StickSet,
    as_model,
    supported_configuration,
)


def _slip_torques(omega: float, rig: RigModel, cfg: Configuration) -> tuple[float, float]:
    d = 1.0 if omega > 0 else -1.0
    y = rig.zero_state()
    tfu = rig.model.upper_slip_torque(omega, d, 0.0, y, rig.p)
    tfl = 0.0 if cfg is Configuration.UPPER else rig.model.lower_slip_torque(omega, d, 0.0, y, rig.p, cfg.brake)
    return tfu, tfl


def _closed_form(cfg: Configuration, omega: float, rig: RigModel) -> tuple[float, float, float, float]:
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


def _refine(cfg: Configuration, omega: float, guess: tuple, rig: RigModel) -> tuple[float, float, float, float, tuple]:
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
        readers = _angle_or_time_readers(rig.comp)
        which = f" ({', '.join(readers)})" if readers else ""
        raise ParameterError(
            f"the model {rig.comp.label!r} has no constant equilibria: its effects{which} depend on the "
            f"disc angles or on time (residual {moved:.2g} after a rotation); run it without them"
        )
    u, st = state(sol)
    return float(u), float(st[1] - st[0]), float(st[4]), float(st[5]), tuple(float(v) for v in st[8:])


def slip_equilibrium(
    config: str | Configuration,
    omega: float,
    params: RigParams | RigModel | None = None,
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
    rig = as_model(params, effects, effect_params)
    cfg = supported_configuration(config)
    rig.comp.refuse_not_acting(cfg.label, "effects")
    omega = real_number("omega", omega, "rad/s")
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
    params: RigParams | RigModel | None = None,
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
    rig = as_model(params, effects, effect_params)
    cfg = supported_configuration(config)
    rig.comp.refuse_not_acting(cfg.label, "effects")
    w = np.atleast_1d(real_numbers("omega", omega, "rad/s"))
    if rig.dynamic_effects:
        out = np.array([slip_equilibrium(cfg, float(v), rig, with_eigenvalues=False).u for v in w])
    else:
        out = np.array([_closed_form(cfg, float(v), rig)[0] for v in w])
    return out if np.ndim(omega) else out[0]


def slip_equilibria(
    config: str | Configuration,
    u: float,
    params: RigParams | RigModel | None = None,
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
    rig = as_model(params, effects, effect_params)
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
    config: str | Configuration, u: float, params: RigParams | RigModel | None = None, effects=None, effect_params=None
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
    rig = as_model(params, effects, effect_params)
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


def _stick_set_numeric(cfg: Configuration, u: float, rig: RigModel, centre: float) -> StickSet | None:
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


def _angle_or_time_readers(comp) -> list[str]:
    """The effects of ``comp`` whose functions read a disc's angle or the time: those that move an equilibrium
    along a rotation (position friction, cogging, a user's effect of ``t``)."""
    reads = {"theta_u", "theta_l", "t"}
    return [
        e.name for e in comp.effects if any(reads.intersection(e.argument_names(fn)) for fn in e.defined_functions())
    ]
