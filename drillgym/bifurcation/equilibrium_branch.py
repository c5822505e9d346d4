"""Equilibrium branches versus constant voltage, with stability and located Hopf points.

The slip branch is parametrised by the speed omega (rad/s) on a geometric grid
(u(omega) from :mod:`drillgym.equilibria`, so folds of the equilibrium branch
and several equilibria per voltage come out naturally).  Stability is the sign
of the largest real part of the linearisation's eigenvalues; a Hopf point is a
sign change of it, located by Brent's method in omega and mapped to the
voltage.  The stick set (omega = 0) occupies 0 <= u <= us.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from ..configurations import Configuration
from ..equilibria import (
    RigModel,
    eigenvalues,
    equilibrium_voltage,
    model_or_params,
    slip_equilibrium,
    stick_set,
    supported_configuration,
)
from ..errors import InputError
from ..params import RigParams
from ..run_setup import real_number, whole_number


@dataclass(frozen=True)
class HopfPoint:
    """A Hopf point of the slip equilibrium branch.

    Parameters
    ----------
    u : float
        Voltage (V).
    omega : float
        Equilibrium speed (rad/s).
    frequency : float
        Frequency of the crossing eigenvalue pair (rad/s).
    direction : str
        ``"loses"`` or ``"gains"``: what the equilibrium does to its stability as u increases.
    """

    u: float
    omega: float
    frequency: float
    direction: str

    def to_dict(self) -> dict:
        return {"u": self.u, "omega": self.omega, "frequency": self.frequency, "direction": self.direction}


@dataclass
class EquilibriumBranch:
    """Slip equilibria along the grid of speeds plus the stick interval [0, u_stick].

    Parameters
    ----------
    config : Configuration
        The rig configuration.
    omega : ndarray
        Speeds of the grid (rad/s).
    u : ndarray
        Voltage of each equilibrium (V).
    alpha : ndarray
        Winding (rad).
    r : ndarray
        Whirl amplitude (m; 0 when the lower disc is held).
    max_real : ndarray
        Largest real part of the eigenvalues (1/s): negative where the equilibrium is stable.
    u_stick : float
        Voltage up to which the stick set exists (V).
    hopf : list of HopfPoint, optional
        The Hopf points on the branch.
    params : RigModel or RigParams, optional
        The model the branch was computed on.
    """

    config: Configuration
    omega: np.ndarray
    u: np.ndarray
    alpha: np.ndarray
    r: np.ndarray
    max_real: np.ndarray
    u_stick: float
    hopf: list[HopfPoint] = field(default_factory=list)
    params: RigModel | RigParams | None = None
    _section_cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def stable(self) -> np.ndarray:
        """Where the equilibrium is stable (bool array over the grid)."""
        return self.max_real < 0

    def section_speed(self, u: float) -> float:
        """Speed (rad/s) of the lowest slip equilibrium at voltage u, used as Poincare section
        (held at the value just above the stick voltage for u below it).

        The grid value is refined to the exact root of u(omega) = u (Brent, bracketed by the two
        grid speeds around it): a linearly interpolated section speed misses a small orbit born at
        a Hopf point where u(omega) is strongly curved (the lateral resonance near 15 rad/s is off
        by 0.02 rad/s on a 300-point grid, more than the orbit's amplitude in omega_l)."""
        key = float(u)
        hit = self._section_cache.get(key)
        if hit is not None:
            return hit
        inc = np.concatenate([[True], np.diff(self.u) > 0])
        stop = int(np.argmin(inc)) if not inc.all() else len(inc)
        uu, ww = self.u[:stop], self.omega[:stop]
        uc = max(key, uu[0] + 1e-4)
        w = float(np.interp(uc, uu, ww))
        i = int(np.searchsorted(uu, uc))
        if self.params is not None and 0 < i < len(uu):
            f = lambda v: float(equilibrium_voltage(self.config, v, self.params)) - uc  # noqa: E731
            lo, hi = float(ww[i - 1]), float(ww[i])
            if f(lo) * f(hi) <= 0:
                w = float(brentq(f, lo, hi, xtol=1e-13, rtol=1e-15))
        if len(self._section_cache) > 4096:
            self._section_cache.clear()
        self._section_cache[key] = w
        return w

    def to_dict(self, every: int = 1) -> list[dict]:
        out = [{"kind": "stick", "u_min": 0.0, "u_max": self.u_stick, "omega": 0.0, "stable": True}]
        for i in range(0, len(self.u), every):
            out.append(
                {
                    "kind": "slip",
                    "u": float(self.u[i]),
                    "omega": float(self.omega[i]),
                    "alpha": float(self.alpha[i]),
                    "r": float(self.r[i]),
                    "stable": bool(self.stable[i]),
                    "max_real_eigenvalue": float(self.max_real[i]),
                }
            )
        return out


def _max_real(cfg: Configuration, w: float, params: RigParams) -> float:
    return float(np.max(eigenvalues(slip_equilibrium(cfg, w, params, with_eigenvalues=False)).real))


def equilibrium_branch(
    config: str | Configuration,
    params: RigParams | RigModel | None = None,
    umax: float = 5.0,
    n: int = 300,
    omega_min: float = 1e-4,
    *,
    model=None,
) -> EquilibriumBranch:
    """The slip equilibrium branch for 0 < u <= umax and its Hopf points.

    Parameters
    ----------
    config : str or Configuration
        Rig configuration.
    params : RigParams or RigModel, optional
        Base parameters, or a model with effects (:func:`drillgym.equilibria.as_model`); default the
        identified set.
    umax : float, optional
        Highest voltage (V).  Default 5.
    n : int, optional
        Number of speeds on the branch.  Default 300.
    omega_min : float, optional
        Lowest speed of the branch (rad/s).
    model : drillgym.Model, str or path, optional
        The rig's model (:class:`drillgym.Model` or a model file's path, read without ``trust``): its base
        parameters, effects and values; refused beside ``params``.

    Returns
    -------
    EquilibriumBranch
        Voltage, speed and stability along the branch, and its Hopf points.
    """
    cfg = supported_configuration(config)
    params = model_or_params(params, model, "equilibrium_branch()", cfg.label)
    umax = real_number("umax", umax, "V")
    if not (np.isfinite(umax) and umax > 0):
        raise InputError(f"umax must be a positive voltage, got {umax!r}")
    n = whole_number("n", n, 2)
    omega_min = real_number("omega_min", omega_min, "rad/s")
    if not (np.isfinite(omega_min) and omega_min > 0):
        raise InputError(f"omega_min must be a positive speed (rad/s), got {omega_min!r}")
    w_hi = 1.0
    while equilibrium_voltage(cfg, w_hi, params) < umax:
        w_hi *= 1.5
        if w_hi > 1e4:
            raise InputError(f"no slip equilibrium reaches u = {umax} V below 1e4 rad/s")
    w = np.geomspace(omega_min, w_hi, n)
    eqs = [slip_equilibrium(cfg, v, params) for v in w]
    u = np.array([e.u for e in eqs])
    keep = u <= umax * 1.0001
    keep[np.argmax(~keep) if not keep.all() else -1] = True  # one point beyond umax closes the curve
    eqs = [e for e, k in zip(eqs, keep) if k]
    w = w[keep]
    mr = np.array([np.max(e.eigenvalues.real) for e in eqs])
    hopf = []
    for i in np.flatnonzero(np.sign(mr[:-1]) != np.sign(mr[1:])):
        wc = brentq(lambda v: _max_real(cfg, v, params), w[i], w[i + 1], xtol=1e-12, rtol=1e-12)
        e = slip_equilibrium(cfg, wc, params)
        freq = float(np.max(np.abs(e.eigenvalues[np.argsort(-e.eigenvalues.real)[:2]].imag)))
        hopf.append(HopfPoint(e.u, wc, freq, "loses" if mr[i] < 0 else "gains"))
    ss = stick_set(cfg, 0.0, params)
    base = params.params
    u_stick = base.stick_voltage if cfg.brake else (base.Tcu + base.dTcu + base.Tcl) / base.km
    if ss is None:
        u_stick = 0.0
    return EquilibriumBranch(
        cfg,
        w,
        np.array([e.u for e in eqs]),
        np.array([e.alpha for e in eqs]),
        np.array([e.r for e in eqs]),
        mr,
        float(u_stick),
        hopf,
        params,
    )
