"""Equilibria of the rig for a constant voltage, their linearisation and stability.

Two kinds of equilibria (report 4.1.1, 4.2, 4.3.1; docs/model.md):

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
  are found by root bracketing in omega).  With effects (``effects=``, a
  composition of :mod:`drillgym.effects`) the closed form of the base model is
  refined by Newton on the composition's compiled ``state_derivative`` residual,
  so the equilibria are those of the simulator, effects included; effects that
  make the rig depend on its angle or on time (no constant equilibria) are refused.

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

Input: ``u`` (V); the states of the composition's effects (e.g. ``u_m`` of
motor_lag) are appended.  A transport delay (Delay effect) is not part of the
finite-dimensional linearisation.  Units: rad, rad/s, m, m/s.  The linear model describes
deviations from the equilibrium (for the angle variant: from the uniformly
rotating equilibrium motion).

:func:`routh_hurwitz_torsional` gives the report's stability analysis of the
torsional slip equilibria: the critical linearised brake damping (R1), the
velocities where stability changes (R2), the Hopf voltages (R3).
"""

from __future__ import annotations

from .linear import FD_STEP, eigenvalues, linearise
from .model import Equilibrium, RigModel, StickSet, as_model, model_or_params, state_names, supported_configuration
from .solutions import equilibrium_voltage, slip_equilibria, slip_equilibrium, stick_set
from .stability import RouthHurwitz, lower_damping, routh_hurwitz_torsional

__all__ = [
    "RigModel",
    "as_model",
    "model_or_params",
    "Equilibrium",
    "StickSet",
    "RouthHurwitz",
    "equilibrium_voltage",
    "slip_equilibrium",
    "slip_equilibria",
    "stick_set",
    "linearise",
    "eigenvalues",
    "routh_hurwitz_torsional",
    "lower_damping",
    "supported_configuration",
    "state_names",
    "FD_STEP",
]
