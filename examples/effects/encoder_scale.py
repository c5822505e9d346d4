"""A motor encoder whose counts per revolution are not the figure the software assumes: a scale error.

A user file for drillgym (docs/EFFECTS.md, "Measurement"):
``--add-effect examples/effects/encoder_scale.py:encoder_scale``.  A Measurement effect: it changes what the
sensor reads, not the motion.
"""

from drillgym.effects import Measurement, Parameter


class EncoderScale(Measurement):
    """The motor encoder reads (1 + enc_scale) theta_u."""

    name = "encoder_scale"
    channels = ("theta_u",)
    parameters = (
        Parameter("enc_scale", "-", -0.05, 0.05, 0.0, 1e-3, "relative scale error of the reading", neutral=0.0),
    )
    configurations = ("upper", "torsional", "lateral", "coupled")
    explanation = (
        "The encoder's counts per revolution differ from the figure the software converts them with (another "
        "disc, a gear ratio off): the reading grows by (1 + enc_scale) rad per radian turned."
    )
    signature = "θu residual growing in proportion to θu itself; θl and the motion fit"

    def measure(theta_u, enc_scale):
        """The motor encoder's reading (rad) of the true angle theta_u."""
        return (1.0 + enc_scale) * theta_u
