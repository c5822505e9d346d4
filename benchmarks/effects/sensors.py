"""The independent rigs' encoder readings, written for drillgym: the exact model of their recordings.

``bench_identify_companions.py --outside`` with the reading kinds of ``bench_diagnosis_rig.OUTSIDE_READING``
compares each recording's identified model with the rig's own model run by drillgym; these are its encoders as
the rig reads them (the motor encoder's scale error is ``examples/effects/encoder_scale.py``).
"""

from drillgym.effects import Measurement, Parameter

_ALL = ("torsional", "lateral", "coupled")


class LowerEncoderScale(Measurement):
    """The lower encoder reads (1 + enc_scale_l) theta_l: its counts per revolution are off."""

    name = "lower_encoder_scale"
    channels = ("theta_l",)
    parameters = (
        Parameter("enc_scale_l", "-", -0.05, 0.05, 0.0, 1e-3, "relative scale error of the reading", neutral=0.0),
    )
    configurations = _ALL
    explanation = "The lower encoder's counts per revolution differ from the figure the software converts them with."
    signature = "θl residual growing in proportion to θl itself"

    def measure(theta_l, enc_scale_l):
        """The lower encoder's reading (rad) of the true angle theta_l."""
        return (1.0 + enc_scale_l) * theta_l


class LowerEncoderOffset(Measurement):
    """The lower encoder reads theta_l + enc_off_l: its zero is off the motor encoder's."""

    name = "lower_encoder_offset"
    channels = ("theta_l",)
    parameters = (Parameter("enc_off_l", "rad", -0.2, 0.2, 0.0, 1e-3, "offset of the reading's zero", neutral=0.0),)
    configurations = _ALL
    explanation = "The encoders were zeroed with the string twisted: the twist they read is off by enc_off_l."
    signature = "a twist residual constant in time; the string torque read off by ktheta enc_off_l"

    def measure(theta_l, enc_off_l):
        """The lower encoder's reading (rad) of the true angle theta_l."""
        return theta_l + enc_off_l
