"""The motor-side candidate terms as effects compiled once: what a discovered candidate's fit runs.

A candidate file written by discovery holds its regressed coefficients, so its source (and the compiled model
of a composition with it) differs for every recording.  Its motor-side terms are fitted instead through these
effects, whose functions are the same terms with every coefficient a parameter (0: the term is off):

* :class:`MotorVoltageTerms` (Input): the motor sees u + o + a sign(u) + b |u| + c u|u| + d u³ + e sat(u, w);
* :class:`UpperTorqueTerms` (Force on the upper disc): a constant and cos/sin kθu for k in
  :data:`.discovery_terms.COGGING_HARMONICS` (cogging);
* the sensors' readings (Measurement effects, :mod:`.reading_terms`): an encoder reads (1 + k) θ + c +
  b tanh(ω / w), an LVDT (1 + k) x + c.

:func:`term_parameters` maps a candidate's term labels to their parameters here.
"""

from __future__ import annotations

import math

from ..effects import Force, Input, Parameter
from .reading_terms import ENCODER_TERM, SENSORS, EncoderTerms

__all__ = [
    "MotorVoltageTerms",
    "SAT_LOWEST",
    "UpperTorqueTerms",
    "EncoderTerms",
    "TERM_EFFECTS",
    "WIDTH_PARAMETERS",
    "width_parameter",
    "term_parameters",
    "HARMONICS",
    "ENCODER_TERM",
]

#: the cogging harmonics (per revolution) the torque terms carry (as :data:`.discovery_terms.COGGING_HARMONICS`)
HARMONICS = (1, 2, 3, 4, 6, 8, 12)


#: the lowest coefficient of sat(u, w): a dead zone.  Below it the voltage at the motor would fall as the command
#: rises inside the width, which no drive does; a fit let go there slid along the valley c w = const to imitate an
#: offset (c = -3, w = 0.096 V for a -0.3 V offset), and the observer built on that model held nothing below 4 rad/s
#: where the same model with the offset held 2.5
SAT_LOWEST = -1.0


class MotorVoltageTerms(Input):
    """The voltage at the motor: u + o + a sign(u) + b |u| + c u|u| + d u³ + e sat(u, w)."""

    name = "motor_voltage_terms"
    parameters = (
        Parameter("mv_offset", "V", -3.0, 3.0, 0.0, 0.05, "constant offset", neutral=0.0),
        Parameter("mv_sign", "V", -3.0, 3.0, 0.0, 0.05, "coefficient of sign(u)", neutral=0.0),
        Parameter("mv_abs", "-", -2.0, 2.0, 0.0, 0.02, "coefficient of |u|", neutral=0.0),
        Parameter("mv_uabs", "1/V", -1.0, 1.0, 0.0, 0.005, "coefficient of u|u|", neutral=0.0),
        Parameter("mv_u3", "1/V²", -0.5, 0.5, 0.0, 0.002, "coefficient of u³", neutral=0.0),
        Parameter("mv_sat", "-", SAT_LOWEST, 3.0, 0.0, 0.1, "coefficient of sat(u, w): -1 is a dead zone", neutral=0.0),
        Parameter("mv_w", "V", 0.0, 3.0, 0.4, 0.1, "width w of sat(u, w)", neutral=0.0),
    )
    configurations = ("upper", "torsional", "lateral", "coupled")
    explanation = "The voltage the motor sees as a function of the voltage entering the drive (discovery's terms)."
    signature = "a residual torque on the upper disc that is a function of the voltage"

    def voltage(u, mv_offset, mv_sign, mv_abs, mv_uabs, mv_u3, mv_sat, mv_w):
        s = 1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0)
        shaped = mv_offset + mv_sign * s + mv_abs * abs(u) + mv_uabs * u * abs(u) + mv_u3 * u**3
        return u + shaped + mv_sat * min(max(u, -mv_w), mv_w)


class UpperTorqueTerms(Force):
    """A torque on the upper disc: a constant and cos/sin kθu (k = 1, 2, 3, 4, 6, 8, 12)."""

    name = "upper_torque_terms"
    acts_on = "upper"
    parameters = (Parameter("ut_1", "N m", -2.0, 2.0, 0.0, 0.01, "constant torque", neutral=0.0),) + tuple(
        Parameter(f"ut_{f}{k}", "N m", -2.0, 2.0, 0.0, 0.01, f"coefficient of {f}({k} θu)", neutral=0.0)
        for k in HARMONICS
        for f in ("c", "s")
    )
    explanation = "A torque on the upper disc that depends on the motor angle (cogging; discovery's terms)."
    signature = "a residual torque on the upper disc periodic in the motor angle"

    def torque(
        theta_u,
        ut_1,
        ut_c1,
        ut_s1,
        ut_c2,
        ut_s2,
        ut_c3,
        ut_s3,
        ut_c4,
        ut_s4,
        ut_c6,
        ut_s6,
        ut_c8,
        ut_s8,
        ut_c12,
        ut_s12,
    ):
        th = theta_u
        return (
            ut_1
            + ut_c1 * math.cos(th)
            + ut_s1 * math.sin(th)
            + ut_c2 * math.cos(2.0 * th)
            + ut_s2 * math.sin(2.0 * th)
            + ut_c3 * math.cos(3.0 * th)
            + ut_s3 * math.sin(3.0 * th)
            + ut_c4 * math.cos(4.0 * th)
            + ut_s4 * math.sin(4.0 * th)
            + ut_c6 * math.cos(6.0 * th)
            + ut_s6 * math.sin(6.0 * th)
            + ut_c8 * math.cos(8.0 * th)
            + ut_s8 * math.sin(8.0 * th)
            + ut_c12 * math.cos(12.0 * th)
            + ut_s12 * math.sin(12.0 * th)
        )


_VOLTAGE = {"sign(u)": "mv_sign", "|u|": "mv_abs", "u|u|": "mv_uabs", "u³": "mv_u3"}


def term_parameters(group: str, label: str) -> str | None:
    """The parameter of a discovery term in :class:`MotorVoltageTerms` or :class:`UpperTorqueTerms`, or of a
    sensor's reading term (:mod:`.reading_terms`).

    Parameters
    ----------
    group : str
        The candidate's group (``motor_voltage``, ``upper_force`` or a sensor's, :data:`.reading_terms.SENSORS`).
    label : str
        The term's label (``sat(u, 0.4)``, ``cos 6θu``, ``1``, ...).

    Returns
    -------
    str or None
        The parameter's name, or None when the term has none here.
    """
    if group in SENSORS:
        return SENSORS[group].terms.get(label)
    if group == "motor_voltage":
        if label == "1":
            return "mv_offset"
        return "mv_sat" if label.startswith("sat(u") else _VOLTAGE.get(label)
    if group == "upper_force":
        if label == "1":
            return "ut_1"
        f, arg = label.split(" ", 1)
        k = arg[: -len("θu")] or "1"
        return f"ut_{f[0]}{k}" if f in ("cos", "sin") and int(k) in HARMONICS else None
    return None


#: a motor-side group -> the effect its terms are fitted through
TERM_EFFECTS = {
    "motor_voltage": MotorVoltageTerms,
    "upper_force": UpperTorqueTerms,
    **{g: s.effect for g, s in SENSORS.items()},
}
#: a group -> the parameter of its terms' scanned width (a dead zone's u0 in V, an encoder's lead speed in rad/s)
WIDTH_PARAMETERS = {"motor_voltage": "mv_w", **{g: s.width for g, s in SENSORS.items() if s.width}}


def width_parameter(group: str) -> Parameter | None:
    """The parameter a group's scanned width is fitted as (its unit and bounds), or None when it has none."""
    name = WIDTH_PARAMETERS.get(group)
    return next((p for p in TERM_EFFECTS[group].parameters if p.name == name), None) if name else None
