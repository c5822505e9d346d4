"""An eccentric lower encoder: its reading is off by an amount that repeats once per revolution.

A user file for drillgym (docs/EFFECTS.md, "Measurement"):
``--add-effect examples/effects/encoder_eccentricity.py:encoder_eccentricity``.  A Measurement effect: it
changes what the sensor reads, not the motion.
"""

import math

from drillgym.effects import Measurement, Parameter


class EncoderEccentricity(Measurement):
    """The lower encoder reads theta_l + e_c cos(theta_l) + e_s sin(theta_l)."""

    name = "encoder_eccentricity"
    channels = ("theta_l",)
    parameters = (
        Parameter("enc_c", "rad", -0.05, 0.05, 0.0, 1e-3, "cos(theta_l) part of the reading error", neutral=0.0),
        Parameter("enc_s", "rad", -0.05, 0.05, 0.0, 1e-3, "sin(theta_l) part of the reading error", neutral=0.0),
    )
    configurations = ("torsional", "lateral", "coupled", "free_vibration")
    explanation = (
        "The lower encoder's code disc is mounted slightly off the shaft's axis: its reading is off by an "
        "error that repeats once per revolution, enc_c cos(θl) + enc_s sin(θl)."
    )
    signature = "θl residual periodic in θl, once per revolution; no residual in θu; the motion itself fits"

    def measure(theta_l, enc_c, enc_s):
        """The lower encoder's reading (rad) of the true angle theta_l."""
        return theta_l + enc_c * math.cos(theta_l) + enc_s * math.sin(theta_l)
