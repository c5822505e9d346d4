"""Torque-feedback active damping in the spirit of soft-torque systems, tuned to the string's torsional mode.

The motor's speed loop (:class:`controllers.pi.MotorSpeedPI`) follows a speed
command that yields to the string torque::

    omega_cmd = omega_ref + HP[T_string] / Z

``T_string = k_theta alpha`` is the torque the string exerts on the upper disc,
estimated on the motor side from the upper disc's equation of motion
(``Ju d omega_u/dt + Tfu(omega_u) - km u``, speed and acceleration from the
quantized motor angle, low-passed).  The high-pass (corner a third of the
torsional mode) removes the mean torque; ``Z`` is the string's characteristic
impedance ``sqrt(k_theta Jl)`` (N m s/rad), which makes the top behave, near the
mode ``sqrt(k_theta / Jl)``, like a damper matched to the string: the industry's
soft-torque tuning.  A passive top impedance can add at most
``k_theta / (2 omega_n) = sqrt(k_theta Jl) / 2`` of damping at the lower disc:
enough where the brake's slope is mildly negative, not at its steepest.

Robust tuning: the torque estimate's error from a wrong motor model is
``(km_true - km_model) u - (bu_true - bu_model) omega_u``, and through ``1 / Z`` (about 18 rad/s per
N m) it feeds back on the speed command: a rig with less viscous friction or a stronger motor than
the model turns it into a positive feedback that destabilises the speed loop (on the plant
population, every plant with bu more than 5 % below the model stick-slipped even at 8 rad/s).  The
estimate therefore uses a biased model, ``km x km_margin`` and ``bu / bu_margin``, at the edge of the
uncertainty set (km +-5 %, bu +-10 %), so that every rig in the set sees a negative (damping) feedback.
"""

from __future__ import annotations

import math

import numpy as np

from drillgym.errors import InputError

from .pi import PIController

__all__ = ["SoftTorqueController"]


class SoftTorqueController(PIController):
    """Soft-torque active damping: the PI motor speed loop, its command yielding to the estimated
    string torque (see the module docstring).

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed(s) (rad/s), as :class:`controllers.Controller`.
    impedance : float, optional
        Impedance Z of the speed command's yield (N m s/rad); None: the string's characteristic
        impedance sqrt(ktheta Jl).
    hp_ratio : float, optional
        Corner of the torque high-pass as a fraction of the torsional mode.  Default 1/3.
    kp, ki : float, optional
        Gains of the PI speed loop (V s/rad, V/rad).  Default 1 and 3.
    velocity_tau : float, optional
        Time constant of the encoder speed estimate's low-pass (s).  Default 0.02.
    torque_tau : float, optional
        Time constant of the string-torque estimate's low-pass (s).  Default 0.5.
    km_margin : float, optional
        Factor on the model's motor constant in the torque estimate (1.05: the edge of a +-5 % set).
    bu_margin : float, optional
        The estimate's upper viscous friction is the model's divided by this factor.
    **kw
        ``config``, ``params``, ``dt``, ``u_max`` of :class:`controllers.Controller`.
    """

    name = "softtorque"
    uses = ("theta_u",)

    def __init__(
        self,
        omega_ref=None,
        *,
        impedance: float | None = None,
        hp_ratio: float = 1.0 / 3.0,
        kp: float = 1.0,
        ki: float = 3.0,
        velocity_tau: float = 0.02,
        torque_tau: float = 0.5,
        km_margin: float = 1.0,
        bu_margin: float = 1.0,
        **kw,
    ) -> None:
        super().__init__(omega_ref, kp=kp, ki=ki, velocity_tau=velocity_tau, **kw)
        p = self.params
        self.omega_n = math.sqrt(p.ktheta / p.Jl)  # torsional mode (rad/s)
        self.impedance = math.sqrt(p.ktheta * p.Jl) if impedance is None else float(impedance)
        if not (self.impedance > 0 and hp_ratio > 0):
            raise InputError(f"impedance and hp_ratio must be positive, got {impedance!r}, {hp_ratio!r}")
        self.a_hp = math.exp(-hp_ratio * self.omega_n * self.dt)  # pole of the low-pass removed by the high-pass
        self.a_tq = math.exp(-self.dt / torque_tau)
        if not (km_margin > 0 and bu_margin > 0):
            raise InputError(f"km_margin and bu_margin must be positive factors, got {km_margin!r}, {bu_margin!r}")
        self.km_model = p.km * float(km_margin)  # N m/V, the torque estimate's motor constant
        self.bu_scale = 1.0 / float(bu_margin)  # factor on the model's viscous friction in the estimate

    def _reset(self, m: dict[str, np.ndarray]) -> None:
        super()._reset(m)  # speed estimator, PI loop, equilibrium feedforward
        self.w_prev = np.zeros(self.n)
        self.u_f = np.zeros(self.n)
        self.torque = np.zeros(self.n)  # low-passed string torque estimate (N m)
        self.mean_torque = None  # slow average (the high-pass's complement)

    def string_torque(self, w: np.ndarray) -> np.ndarray:
        """String torque on the upper disc (N m) from the motor side, low-passed."""
        p = self.params
        acc = (w - self.w_prev) / self.dt
        self.w_prev = w.copy()
        b = self.bu_scale
        tfu = np.where(
            w > 0,
            p.Tcu + p.dTcu + b * (p.bu + p.dbu) * w,
            np.where(w < 0, -(p.Tcu - p.dTcu) + b * (p.bu - p.dbu) * w, 0.0),
        )
        # the voltage through the same low-pass as the speed estimate, so the motor torque cancels exactly
        self.u_f = self.speed.a * self.u_f + (1 - self.speed.a) * self.u_prev
        raw = p.Ju * acc + tfu - self.km_model * self.u_f
        self.torque = self.a_tq * self.torque + (1 - self.a_tq) * raw
        return self.torque

    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        w = self.speed.update(m["theta_u"]).copy()
        tq = self.string_torque(w)
        if self.mean_torque is None:
            self.mean_torque = tq.copy()
        self.mean_torque = self.a_hp * self.mean_torque + (1 - self.a_hp) * tq
        cmd = self.omega_ref + (tq - self.mean_torque) / self.impedance
        return self.loop(cmd, w, self.u_ff)
