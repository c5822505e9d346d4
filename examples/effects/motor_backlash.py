"""Backlash between the motor's shaft and the upper disc, as the motor encoder reads it.

A user file for drillgym (docs/EFFECTS.md, "Measurement"):
``--add-effect examples/effects/motor_backlash.py:motor_backlash``.  A Measurement effect: it changes what the
motor encoder reads, not the motion.
"""

import math

from drillgym.effects import Measurement, Parameter


class MotorBacklash(Measurement):
    """The motor encoder reads theta_u + play tanh(omega_u / w_play)."""

    name = "motor_backlash"
    channels = ("theta_u",)
    parameters = (
        Parameter("play", "rad", -0.1, 0.1, 0.0, 2e-3, "half the gap between the shaft and the disc", neutral=0.0),
        Parameter("w_play", "rad/s", 1e-3, 2.0, 0.05, 0.02, "speed over which the shaft's lead changes side"),
    )
    explanation = (
        "The encoder sits on the motor's shaft, which drives the upper disc through a coupling with free play of "
        "±play. The motor pushes the disc, so its shaft leads the disc by play in the direction the disc turns: the "
        "encoder reads θu + play sign(ωu), the sign smoothed over speeds of about w_play."
    )
    signature = "θu residual that steps by 2 play where the upper disc reverses; θl and the motion fit"

    def measure(theta_u, omega_u, play, w_play):
        """The motor encoder's reading (rad) of the upper disc's angle theta_u."""
        return theta_u + play * math.tanh(omega_u / w_play)
