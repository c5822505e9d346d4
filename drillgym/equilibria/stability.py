"""Stability of the torsional slip equilibria: the lower friction's damping and the report's Routh-Hurwitz analysis."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ..configurations import Configuration
from ..params import RigParams
from .model import (
    RigModel,
    as_model,
)
from .solutions import equilibrium_voltage


def lower_damping(
    omega: float | np.ndarray,
    params: RigParams | RigModel | None = None,
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
    rig = as_model(params, effects, effect_params)
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
