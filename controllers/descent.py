"""Reach the target from above along the stable equilibrium branch: a controller for a rig that is
not its model.

From rest the rig falls into stick-slip for every voltage up to the second fold (R7, R9), although
its slip equilibrium is stable from the second Hopf point (omega_2 = 2.83 rad/s) up.  This
controller uses the bifurcation diagram instead of a model inversion:

1. **approach**: the voltage of the equilibrium at ``approach`` rad/s (default: the fastest one
   the amplifier reaches, ``approach_fraction`` of its range), above the fold, where no stick-slip
   cycle exists, held for ``hold`` s;
2. **descent**: the voltage ramps down over ``ramp`` s to the target's equilibrium voltage; the
   rig follows the stable branch (a slow ramp keeps it near the equilibrium);
3. **hold**: from the start of the descent, integral action on what is measured, the motor angle
   against the integral of the commanded speed (``ki``, V per rad): a rig whose motor, friction
   or brake differ from the model still turns at the commanded speed on average, and so does the
   lower disc (the winding is constant in steady state).

Nothing here inverts the model, so km, bu, brake, inertia and stiffness errors, motor lags,
input delays, coarse or noisy encoders only shift the equilibrium voltage, which the integral
absorbs.  What it cannot do is hold where the equilibrium is unstable: below omega_2 (shifted by
the brake's Stribeck velocity) it sticks and slips like the open loop.  There a controller must
damp the lower disc actively, and with the motor angle as its only measurement no linear
controller can do so robustly to a few percent of model error (:mod:`controllers.limits`).
"""

from __future__ import annotations

import numpy as np

from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError

from .base import Controller

__all__ = ["DescentController"]


class DescentController(Controller):
    """Open-loop approach from above the fold, a slow ramp down the stable branch, integral action on
    the measured motor angle.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    approach : float, optional
        Speed of the approach (rad/s); None: the equilibrium at ``approach_fraction`` x u_max.
    approach_fraction : float, optional
        Fraction of the amplifier's range for the default approach.  Default 0.98.
    hold : float, optional
        Time at the approach speed before the descent (s).  Default 8.
    ramp : float, optional
        Duration of the linear voltage ramp down to the target's equilibrium voltage (s).  Default 25.
    ki : float, optional
        Integral gain on the motor-angle error (V/rad; 0: pure open loop).  Default 0.05.
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "descent"
    uses = ("theta_u",)
    default_dt = 0.01

    def __init__(
        self,
        omega_ref=None,
        *,
        approach: float | None = None,
        approach_fraction: float = 0.98,
        hold: float = 8.0,
        ramp: float = 25.0,
        ki: float = 0.05,
        **kw,
    ) -> None:
        super().__init__(omega_ref, **kw)
        for name, v in (("hold", hold), ("ramp", ramp), ("ki", ki)):
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{name} must be a non-negative number, got {v!r}")
        if not (0 < approach_fraction <= 1):
            raise InputError(f"approach_fraction must be in (0, 1], got {approach_fraction!r}")
        if approach is not None and not (np.isfinite(approach) and approach > 0):
            raise InputError(f"approach must be a positive speed (rad/s), got {approach!r}")
        self.hold, self.ramp, self.ki = float(hold), float(ramp), float(ki)
        self.u_approach = (
            approach_fraction * self.u_max
            if approach is None
            else float(equilibrium_voltage(self.config, float(approach), self.params))
        )
        if self.u_approach > self.u_max:
            raise InputError(
                f"approach speed {approach} rad/s needs {self.u_approach:.2f} V, beyond the "
                f"amplifier's {self.u_max:g} V"
            )

    def approach_time(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """Time (s) until the voltage reaches the target's equilibrium voltage, plus 5 s of settling
        for the integral (targets whose voltage is above the approach's: 5 s)."""
        u = np.asarray(equilibrium_voltage(self.config, np.asarray(omega_ref, dtype=float), self.params))
        return np.where(u < self.u_approach, self.hold + self.ramp, 0.0) + 5.0

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        self.t = 0.0
        self.u_target = (
            np.broadcast_to(equilibrium_voltage(self.config, self.omega_ref, self.params), (self.n,))
            .astype(float)
            .copy()
        )
        self.descends = self.u_target < self.u_approach
        self.theta0 = np.broadcast_to(m.get("theta_u", 0.0), (self.n,)).astype(float).copy()
        self.reference_angle = np.zeros(self.n)  # integral of the commanded speed since the descent began (rad)
        self.integrating = False

    def commanded(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(feedforward voltage (V), commanded lower speed (rad/s)) at time t (s)."""
        s = float(np.clip((t - self.hold) / self.ramp, 0.0, 1.0)) if self.ramp > 0 else float(t >= self.hold)
        u = np.where(self.descends, self.u_approach + s * (self.u_target - self.u_approach), self.u_target)
        return u, self._speed_of(u)

    def _speed_of(self, u: np.ndarray) -> np.ndarray:
        """The model's equilibrium speed (rad/s) at voltage u (V): u(omega) is monotonic (the motor's
        viscous friction outweighs the brake's negative slope), so a table inverts it."""
        if not hasattr(self, "_table"):
            w = np.geomspace(1e-2, 40.0, 400)
            self._table = (np.asarray(equilibrium_voltage(self.config, w, self.params)), w)
        u_grid, w_grid = self._table
        return np.interp(u, u_grid, w_grid)

    def _compiled_law(self):
        """The law as compiled code (:mod:`controllers.compiled.descent_law`), from the current state."""
        from .compiled import CompiledLaw
        from .compiled.descent_law import descent_constants, descent_state, descent_step

        self._speed_of(np.zeros(1))  # the equilibrium table
        u_grid, w_grid = self._table
        state = descent_state(self.t, self.u_target, self.descends, self.theta0, self.reference_angle, self.integrating)
        consts = descent_constants(self.hold, self.ramp, self.ki, self.u_approach, self.dt, u_grid, w_grid)
        return CompiledLaw(descent_step, state, consts)

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        u_ff, w_cmd = self.commanded(self.t)
        if self.t >= self.hold:  # integral from the start of the descent on
            if not self.integrating:
                self.integrating = True
                self.theta0 = np.asarray(m["theta_u"], dtype=float).copy()
            error = (np.asarray(m["theta_u"], dtype=float) - self.theta0) - self.reference_angle  # rad
            u_ff = u_ff - self.ki * error
            self.reference_angle = self.reference_angle + w_cmd * self.dt
        self.t += self.dt
        return np.clip(u_ff, -self.u_max, self.u_max)
