"""A dead zone in the motor drive: small voltages do not reach the motor.

A user file for drillgym (docs/EFFECTS.md, "Input"): ``--add-effect examples/effects/motor_dead_zone.py:dead_zone``.
An Input effect: it transforms the voltage on its way from the command to the motor.
"""

from drillgym.effects import Input, Parameter


class DeadZone(Input):
    """The motor sees sign(u) max(|u| - u0, 0) for the voltage u entering the effect."""

    name = "dead_zone"
    parameters = (
        Parameter(
            "u0",
            unit="V",
            lo=0.0,
            hi=2.0,
            guess=0.1,
            scale=0.05,
            doc="half-width of the dead zone of the motor drive",
            neutral=0.0,
        ),
    )
    configurations = ("upper", "torsional", "lateral", "coupled")  # the motor drives the rig in these
    explanation = (
        "The amplifier and the motor's brushes do not pass small voltages: below u0 in magnitude the motor "
        "gets nothing, above it the voltage less u0. The motor sees sign(u) max(|u| - u0, 0)."
    )
    signature = (
        "the upper disc starts later and turns slower than the model on small commands; the torque residual on "
        "the upper disc is -km u0 sign(u), and -km u inside the dead zone"
    )

    def voltage(u, u0):
        """Voltage at the motor side of the effect (V) for the voltage u entering it."""
        if u > u0:
            return u - u0
        if u < -u0:
            return u + u0
        return 0.0
