"""Bifurcation-based baseline: open loop, the constant voltage whose stable equilibrium is the target.

For a target speed omega_ref the baseline applies ``u = u_eq(omega_ref)``
(:func:`drillgym.equilibria.equilibrium_voltage`).  Whether the rig reaches that
equilibrium from rest is read off the open-loop bifurcation analysis
(:func:`stick_slip_region`): between the first Hopf point of the slip branch
(:func:`drillgym.bifurcation.equilibrium_branch`) and the second fold (where
the stick-slip cycle that the rig falls into from rest disappears; located by a
brute-force sweep from rest, :func:`drillgym.bifurcation.sweep_constant`) the
rig sticks and slips.  :meth:`BaselineController.regime` states it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from drillgym import Configuration, RigParams, parse_configuration
from drillgym.equilibria import equilibrium_voltage, slip_equilibria
from drillgym.errors import InputError

from .base import Controller

__all__ = ["BaselineController", "StickSlipRegion", "stick_slip_region"]

FOLD_SEARCH = (2.5, 5.0)  # V, where the second fold is looked for
STICK_SLIP_FRACTION = 1e-3  # stuck fraction of the steady window above which a run counts as stick-slip


@dataclass(frozen=True)
class StickSlipRegion:
    """Targets (rad/s) and voltages (V) for which the open-loop rig sticks and slips from rest."""

    config: Configuration
    omega_lo: float  # speed of the first Hopf point (slip equilibria unstable above it, up to the second Hopf)
    omega_hi: float  # speed of the stable equilibrium at the second fold
    u_hopf: float
    u_fold: float

    def contains(self, omega: float | np.ndarray) -> bool | np.ndarray:
        w = np.asarray(omega, dtype=float)
        out = (w > self.omega_lo) & (w < self.omega_hi)
        return bool(out) if out.ndim == 0 else out


@lru_cache(maxsize=16)
def stick_slip_region(
    config: str | Configuration, params: RigParams | None = None, resolution: float = 0.01
) -> StickSlipRegion:
    """Where stick-slip is what the open-loop rig does from rest (first Hopf point to second fold).

    The Hopf point comes from the eigenvalues along the equilibrium branch; the fold from two
    sweeps from rest (0.1 V grid, then ``resolution`` V) of 120 s runs.
    """
    from drillgym.bifurcation import equilibrium_branch, sweep_constant

    params = params or RigParams()
    cfg = parse_configuration(config)
    branch = equilibrium_branch(cfg, params, umax=FOLD_SEARCH[1])
    if not branch.hopf:
        raise InputError(f"no Hopf point on the {config} slip branch: no stick-slip region")
    h = branch.hopf[0]

    def last_stick_slip(volts: np.ndarray) -> float:
        sw = sweep_constant(cfg.label, volts, params=params)
        ss = volts[np.asarray(sw.stick_fraction) > STICK_SLIP_FRACTION]
        return float(ss.max()) if ss.size else float(volts[0])

    coarse = np.arange(FOLD_SEARCH[0], FOLD_SEARCH[1] + 1e-9, 0.1)
    u1 = last_stick_slip(coarse)
    u_fold = last_stick_slip(np.arange(u1, u1 + 0.1 + 1e-9, resolution))
    eqs = [e for e in slip_equilibria(cfg, u_fold, params) if e.stable]
    w_hi = max(e.omega for e in eqs) if eqs else float("nan")
    return StickSlipRegion(cfg, float(h.omega), float(w_hi), float(h.u), float(u_fold))


class BaselineController(Controller):
    """Open loop: the constant voltage of the stable slip equilibrium at the target speed.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    config, params, dt, u_max : optional
        As :class:`controllers.Controller`.
    """

    name = "baseline"
    uses = ()

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        self.u_eq = np.asarray(equilibrium_voltage(self.config, self.omega_ref, self.params), dtype=float)
        self.u_eq = np.broadcast_to(self.u_eq, (self.n,)).copy()

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        return self.u_eq

    def regime(self, omega_ref: float | None = None) -> str:
        """What the open-loop rig does at the target, from the bifurcation analysis (one sentence)."""
        w = float(self.omega_ref[0] if omega_ref is None else omega_ref)
        reg = stick_slip_region(self.config.label, self.params)
        u = float(equilibrium_voltage(self.config, w, self.params))
        if reg.contains(w):
            return (
                f"target {w:.2f} rad/s (u = {u:.3f} V) lies in the stick-slip region "
                f"{reg.omega_lo:.3f}-{reg.omega_hi:.2f} rad/s ({self.config.label}): from rest the rig sticks and slips"
            )
        return (
            f"target {w:.2f} rad/s (u = {u:.3f} V): the stable equilibrium is reached from rest ({self.config.label})"
        )
