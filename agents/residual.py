"""Residual policy structure: the agent corrects the feedforward voltage of the target.

The policy outputs ``a`` in [-1, 1]; the motor voltage is

    u = clip(u_ff(omega_ref) + scale * a, -5 V, 5 V)

with ``u_ff`` the voltage of the slip equilibrium at the target speed
(:func:`drillgym.equilibria.equilibrium_voltage`, the bifurcation baseline's
open-loop voltage) on the model the agent is designed on.  ``a = 0`` is the
baseline, so exploration starts from a sensible controller and the network
only has to learn the stick-slip suppression.  ``omega_ref`` is read from the
last entry of the observation (every drillgym observation mode ends with it).

The same :class:`ResidualVoltage` is applied in training
(:class:`agents.envs.ResidualActionVecEnv`, an SB3 ``VecEnvWrapper``), in the exported policy
(:class:`agents.export.ExportedPolicy`) and on the rig (:class:`agents.controller.AgentController`).
"""

from __future__ import annotations

import numpy as np

from drillgym import RigParams
from drillgym.envs.options import U_MAX
from drillgym.equilibria import equilibrium_voltage

__all__ = ["ResidualVoltage"]


class ResidualVoltage:
    """Maps (target speed, policy action in [-1, 1]) -> motor voltage (V).

    Args:
        config: rig configuration whose equilibria give the feedforward ('torsional', 'coupled', ...).
        scale: voltage of a full action (V), > 0.
        params: model of the feedforward (default: the identified set).
    """

    def __init__(self, config: str, scale: float, params: RigParams | None = None) -> None:
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"residual scale must be a positive voltage, got {scale!r}")
        self.config = config
        self.scale = float(scale)
        self.params = params or RigParams()
        self._ref = np.zeros(0)
        self._uff = np.zeros(0)

    def feedforward(self, omega_ref: np.ndarray) -> np.ndarray:
        """u_ff (V) for targets (rad/s), cached: recomputed only where the target changed."""
        w = np.asarray(omega_ref, dtype=float).reshape(-1)
        if self._ref.shape != w.shape:
            self._ref, self._uff = np.full(w.shape, np.nan), np.zeros(w.shape)
        changed = np.flatnonzero(w != self._ref)
        if changed.size:
            self._uff[changed] = np.atleast_1d(equilibrium_voltage(self.config, w[changed], self.params))
            self._ref[changed] = w[changed]
        return self._uff

    def voltage(self, action: np.ndarray, omega_ref: np.ndarray) -> np.ndarray:
        """Voltages (n,) for actions (n,) or (n, 1) and targets (n,) (rad/s)."""
        a = np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0)
        return np.clip(self.feedforward(omega_ref) + self.scale * a, -U_MAX, U_MAX)
