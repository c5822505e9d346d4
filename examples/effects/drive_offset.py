"""An offset in the motor drive: the motor sees the command plus a constant voltage.

A user file for drillgym (docs/EFFECTS.md, "Input"): ``--add-effect examples/effects/drive_offset.py:drive_offset``.
An Input effect: it transforms the voltage on its way from the command to the motor.
"""

from drillgym.effects import Input, Parameter


class DriveOffset(Input):
    """The motor sees u + u_off for the voltage u entering the effect."""

    name = "drive_offset"
    parameters = (
        Parameter("u_off", unit="V", lo=-1.0, hi=1.0, guess=0.0, scale=0.05, doc="offset of the drive", neutral=0.0),
    )
    configurations = ("upper", "torsional", "lateral", "coupled")  # the motor drives the rig in these
    explanation = (
        "The amplifier's output is off by a constant voltage (an unbalanced output stage, a zero that drifted): "
        "the motor sees the command plus u_off."
    )
    signature = "a constant torque residual km u_off on the upper disc, in the same direction at every speed"

    def voltage(u, u_off):
        """Voltage at the motor side of the effect (V) for the voltage u entering it."""
        return u + u_off
