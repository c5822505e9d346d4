"""Residual policy structure: the agent corrects a model-based feedforward voltage.

The policy outputs ``a`` in [-1, 1]; the motor voltage is

    u = clip(u_ff(omega_ref, t) + scale * a, -5 V, 5 V)

``u_ff`` is the voltage of the slip equilibrium at the target speed
(:func:`drillgym.equilibria.equilibrium_voltage`, the bifurcation baseline's
open-loop voltage) on the model the agent is designed on; ``a = 0`` is the
baseline, so exploration starts from a sensible controller.  ``omega_ref`` is read
from the last entry of the observation (every drillgym observation mode ends with it).

Optional start-up schedule (``startup = (kick, hold, ramp)``; V, s, s): the
bifurcation diagram's way around stick-slip from rest.  Below the second fold the
rig started from rest at u_ff falls onto the stick-slip cycle although the
equilibrium is stable (coexistence); started above the fold (``kick`` volts for
``hold`` seconds) and brought down slowly (linear ``ramp`` to u_ff), it follows
the stable equilibrium branch.  ``t`` is the time since the episode (run) began::

    u_ff(omega_ref, t) = kick                                   t < hold
                         kick + (u_eq - kick) (t - hold) / ramp  hold <= t < hold + ramp
                         u_eq(omega_ref)                         later

The same :class:`ResidualVoltage` is applied in training
(:class:`agents.envs.ResidualActionVecEnv`, an SB3 ``VecEnvWrapper``), in the
exported policy's controller and on the rig (:class:`agents.controller.AgentController`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from drillgym import RigParams
from drillgym.envs.options import U_MAX
from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError

__all__ = ["ResidualVoltage"]


class ResidualVoltage:
    """Maps (policy action in [-1, 1], target speed, time since start) -> motor voltage (V).

    Parameters
    ----------
    config : str
        Rig configuration whose equilibria give the feedforward ('torsional', 'coupled', ...).
    scale : float
        Voltage of a full action (V), > 0.
    params : RigParams, optional
        Model of the feedforward (default: the identified set).
    startup : sequence of float, optional
        (kick V, hold s, ramp s) start-up schedule, or None (constant u_eq).
    """

    def __init__(
        self, config: str, scale: float, params: RigParams | None = None, startup: Sequence[float] | None = None
    ) -> None:
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"residual scale must be a positive voltage, got {scale!r}")
        if startup is not None:
            if len(startup) != 3 or not all(np.isfinite(v) for v in startup):
                raise InputError(f"startup must be (kick V, hold s, ramp s), got {startup!r}")
            kick, hold, ramp = (float(v) for v in startup)
            if not (abs(kick) <= U_MAX and hold >= 0 and ramp > 0):
                raise InputError(f"startup needs |kick| <= {U_MAX} V, hold >= 0 s, ramp > 0 s; got {startup!r}")
            startup = (kick, hold, ramp)
        self.config = config
        self.scale = float(scale)
        self.params = params or RigParams()
        self.startup = startup
        self._ref = np.zeros(0)
        self._ueq = np.zeros(0)

    def equilibrium(self, omega_ref: np.ndarray) -> np.ndarray:
        """u_eq (V) for targets (rad/s), cached: recomputed only where the target changed."""
        w = np.asarray(omega_ref, dtype=float).reshape(-1)
        if self._ref.shape != w.shape:
            self._ref, self._ueq = np.full(w.shape, np.nan), np.zeros(w.shape)
        changed = np.flatnonzero(w != self._ref)
        if changed.size:
            self._ueq[changed] = np.atleast_1d(equilibrium_voltage(self.config, w[changed], self.params))
            self._ref[changed] = w[changed]
        return self._ueq

    def feedforward(self, omega_ref: np.ndarray, t: float | np.ndarray = np.inf) -> np.ndarray:
        """u_ff (V) for targets (rad/s) at times since start ``t`` (s)."""
        u = self.equilibrium(omega_ref)
        if self.startup is None:
            return u.copy()
        kick, hold, ramp = self.startup
        s = np.clip((np.asarray(t, dtype=float) - hold) / ramp, 0.0, 1.0)
        return kick + (u - kick) * s

    def voltage(self, action: np.ndarray, omega_ref: np.ndarray, t: float | np.ndarray = np.inf) -> np.ndarray:
        """Voltages (n,) for actions (n,) or (n, 1), targets (n,) (rad/s), times since start (s)."""
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        return np.clip(self.feedforward(omega_ref, t) + self.scale * a, -U_MAX, U_MAX)
