"""PI speed control on the motor velocity: the stiff field default.

The motor speed is estimated from the quantized motor angle
(:class:`drillgym.measurement.EncoderVelocityEstimator`: backward difference
and a first-order low-pass).  The voltage is the feedforward of the target's
equilibrium (:func:`drillgym.equilibria.equilibrium_voltage`) plus a PI on the
speed error, with anti-windup by conditional integration at the voltage limit.
A stiff speed loop holds the upper disc at omega_ref whatever the string does:
the lower disc then sees a fixed end and sticks and slips wherever the brake's
slope is negative.
"""

from __future__ import annotations

import numpy as np

from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError
from drillgym.measurement import EncoderVelocityEstimator

from .base import Controller

__all__ = ["PIController", "MotorSpeedPI"]


class MotorSpeedPI:
    """Batched PI speed loop: u = u_ff + kp e + ki integral(e), e = omega_cmd - omega_u (V, rad/s).

    Parameters
    ----------
    n : int
        Number of rigs.
    dt : float
        Control period (s).
    kp : float
        Proportional gain (V s/rad), >= 0.
    ki : float
        Integral gain (V/rad), >= 0.
    u_max : float
        Voltage limit (V); the integral stops winding up at it.
    """

    def __init__(self, n: int, dt: float, kp: float, ki: float, u_max: float) -> None:
        if kp < 0 or ki < 0:
            raise InputError(f"PI gains must be non-negative, got kp={kp!r}, ki={ki!r}")
        self.dt, self.kp, self.ki, self.u_max = dt, kp, ki, u_max
        self.integral = np.zeros(n)

    def __call__(self, omega_cmd: np.ndarray, omega_u: np.ndarray, u_ff: np.ndarray) -> np.ndarray:
        e = omega_cmd - omega_u
        u = u_ff + self.kp * e + self.ki * self.integral
        saturated = (np.abs(u) >= self.u_max) & (np.sign(e) == np.sign(u))
        self.integral = np.where(saturated, self.integral, self.integral + e * self.dt)
        return np.clip(u_ff + self.kp * e + self.ki * self.integral, -self.u_max, self.u_max)


class PIController(Controller):
    """PI speed control of the motor (upper disc) at the target speed, speed from the motor encoder.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    kp : float, optional
        Proportional gain (V s/rad).  Default 3.
    ki : float, optional
        Integral gain (V/rad).  Default 10.
    velocity_tau : float, optional
        Time constant of the encoder speed estimate's low-pass (s).  Default 0.02.
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "pi"
    uses = ("theta_u",)

    def __init__(self, omega_ref=None, *, kp: float = 3.0, ki: float = 10.0, velocity_tau: float = 0.02, **kw) -> None:
        super().__init__(omega_ref, **kw)
        self.kp, self.ki, self.velocity_tau = float(kp), float(ki), float(velocity_tau)

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        self.speed = EncoderVelocityEstimator(self.n, self.dt, self.velocity_tau)
        self.speed.reset(np.broadcast_to(m.get("theta_u", 0.0), (self.n,)).copy())
        self.loop = MotorSpeedPI(self.n, self.dt, self.kp, self.ki, self.u_max)
        self.u_ff = np.broadcast_to(equilibrium_voltage(self.config, self.omega_ref, self.params), (self.n,)).copy()

    def _compiled_law(self):
        """The PI loop as a compiled law (:mod:`controllers.compiled.pi_law`), from the current state."""
        from .compiled import CompiledLaw
        from .compiled.pi_law import pi_constants, pi_state, pi_step

        s, loop = self.speed, self.loop
        state = pi_state(s.prev, s.omega, loop.integral, self.u_ff, self.omega_ref)
        return CompiledLaw(pi_step, state, pi_constants(s.a, s.dt, loop.kp, loop.ki, loop.u_max))

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        w = self.speed.update(m["theta_u"])
        return self.loop(self.omega_ref, w, self.u_ff)
