"""The independent motor rig's effects outside the library, written for drillgym: the exact model of its recordings.

``bench_identify_companions.py`` compares each recording's identified model with the rig's own model run by
drillgym (its base parameters, its library effects and these, at the values drawn): what the comparison leaves
with the exact model is the floor no identified model can be judged against.  The physics is
``bench_diagnosis_motor.py``'s, paragraph by paragraph; the drive's dead zone and offset are
``examples/effects/motor_dead_zone.py`` and ``examples/effects/drive_offset.py``.
"""

import math

from drillgym.effects import Force, Input, Parameter

_DRIVE = ("upper", "torsional", "lateral", "coupled")


class Saturation(Input):
    """The motor sees v (1 - s v^2) of the voltage v reaching it (a motor constant falling with the voltage)."""

    name = "saturation"
    parameters = (
        Parameter("s", "1/V^2", 0.0, 0.05, 0.0, 1e-3, "fall of the gain with the voltage squared", neutral=0.0),
    )
    configurations = _DRIVE
    explanation = "The drive's gain falls with the voltage: the motor sees v (1 - s v^2)."
    signature = "a torque residual on the upper disc of -km s u^3"

    def voltage(u, s):
        """Voltage at the motor (V)."""
        return u * (1.0 - s * u * u)


class Cogging(Force):
    """A torque -Tcog sin(6 theta_u + phase) on the upper disc: six detents per revolution."""

    name = "cogging"
    acts_on = "upper"
    parameters = (
        Parameter("Tcog", "N m", 0.0, 0.5, 0.0, 0.01, "amplitude of the cogging torque", neutral=0.0),
        Parameter("phase", "rad", -10.0, 10.0, 0.0, 0.1, "phase of the detents"),
    )
    configurations = _DRIVE
    explanation = "The motor's magnets pull its rotor towards six detents a revolution."
    signature = "a torque residual on the upper disc periodic six times per revolution"

    def torque(theta_u, Tcog, phase):
        """Torque on the upper disc (N m)."""
        return -Tcog * math.sin(6.0 * theta_u + phase)
