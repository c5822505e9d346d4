"""What a sensor reads, as Measurement effects compiled once: the terms of the diagnosis' reading candidates.

A sensor that reads a little off its true value leaves no torque to regress (:mod:`.discovery` reads the residual
torques); its reading is fitted instead (:mod:`.sensor_reading`) through one of these effects, whose function is
the reading with every coefficient a parameter (0: the sensor reads the true value):

* :class:`EncoderTerms` (Measurement of ``theta_u`` and ``theta_l``): each encoder reads (1 + k) θ + c +
  b tanh(ω / w): a scale error k (its counts per revolution are off by k), an offset c, and free play b between
  its shaft and the disc (the shaft leads the disc by b in the direction it turns);
* :class:`LvdtTerms` (Measurement of ``X`` and ``Y``): each LVDT reads (1 + k) x + c, a gain error k and an
  offset c.

A sensor's candidate frees only its own parameters; the other sensors' stay at 0 (their play's width at its
guess), so one compiled effect serves both encoders, and one both LVDTs.

:data:`SENSORS` describes each sensor: the channel its residual is judged on, its effect, its terms' labels,
parameters and code, and the words that say what a fitted reading means (:func:`reading_words`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..effects import Measurement, Parameter

__all__ = [
    "EncoderTerms",
    "LvdtTerms",
    "ReadingSensor",
    "SENSORS",
    "ENCODER_TERM",
    "reading_words",
]

#: the label of the motor encoder's play term (what the backlash candidate has always been called)
ENCODER_TERM = "tanh(ωu/w)"


def _encoder_parameters(p: str) -> tuple[Parameter, ...]:
    """An encoder's reading terms: scale error (-), offset (rad), play (rad) and its width (rad/s), named ``p_*``."""
    return (
        Parameter(f"{p}_scale", "-", -0.2, 0.2, 0.0, 1e-3, "reading's scale error k", neutral=0.0),
        Parameter(f"{p}_offset", "rad", -0.5, 0.5, 0.0, 1e-3, "offset of the reading", neutral=0.0),
        Parameter(f"{p}_play", "rad", -0.2, 0.2, 0.0, 2e-3, "half the free play the shaft leads by", neutral=0.0),
        Parameter(f"{p}_w", "rad/s", 1e-3, 2.0, 0.05, 0.02, "speed over which the lead changes side"),
    )


def _lvdt_parameters(p: str) -> tuple[Parameter, ...]:
    """An LVDT's reading terms: gain error (-) and offset (m), named ``p_*``."""
    return (
        Parameter(f"{p}_scale", "-", -0.2, 0.2, 0.0, 1e-3, "gain's scale error k", neutral=0.0),
        Parameter(f"{p}_offset", "m", -0.01, 0.01, 0.0, 1e-5, "offset of the reading", neutral=0.0),
    )


class EncoderTerms(Measurement):
    """The encoders' readings: (1 + me_scale) θu + me_offset + me_play tanh(ωu / me_w) and the same of θl with
    ``le_*``."""

    name = "encoder_terms"
    channels = ("theta_u", "theta_l")
    parameters = _encoder_parameters("me") + _encoder_parameters("le")
    configurations = ("torsional", "lateral", "coupled")
    explanation = (
        "An encoder reads its shaft with a scale error (counts per revolution), an offset, and free play between "
        "the shaft and its disc: the shaft leads the disc by the play in the direction it turns (the diagnosis' "
        "reading terms; me_* the motor encoder, le_* the lower one)."
    )
    signature = "an angle residual that grows with the angle turned, or changes side where the disc reverses"

    def measure(
        theta_u, theta_l, omega_u, omega_l, me_scale, me_offset, me_play, me_w, le_scale, le_offset, le_play, le_w
    ):
        tu = theta_u + me_scale * theta_u + me_offset + me_play * math.tanh(omega_u / me_w)
        return tu, theta_l + le_scale * theta_l + le_offset + le_play * math.tanh(omega_l / le_w)


class LvdtTerms(Measurement):
    """The LVDTs' readings: (1 + lx_scale) X + lx_offset and (1 + ly_scale) Y + ly_offset."""

    name = "lvdt_terms"
    channels = ("X", "Y")
    parameters = _lvdt_parameters("lx") + _lvdt_parameters("ly")
    configurations = ("lateral", "coupled")
    explanation = "The LVDTs read the disc's x and y with a gain error and an offset (the diagnosis' reading terms)."
    signature = "an x or y residual proportional to x or y, or constant"

    def measure(X, Y, lx_scale, lx_offset, ly_scale, ly_offset):
        return X + lx_scale * X + lx_offset, Y + ly_scale * Y + ly_offset


@dataclass(frozen=True)
class ReadingSensor:
    """One sensor whose reading the diagnosis can propose as a candidate.

    Attributes
    ----------
    group : str
        The candidate's group (``motor_encoder``, ``lower_encoder``, ``lvdt_x``, ``lvdt_y``).
    channel : str
        The objective's channel its residual is judged on (``theta_u``, ``theta_l``, ``x``, ``y``).
    effect : type of Measurement
        The readings' terms compiled once (:class:`EncoderTerms` or :class:`LvdtTerms`).
    what : str
        The sensor in words (``the lower encoder``).
    symbol : str
        The true quantity it reads (``θl``).
    variable, speed : str
        The Measurement channel it reads (``theta_l``, ``X``: ``measure``'s first argument in a written file) and
        the disc's speed (rad/s; empty for an LVDT).
    unit : str
        The reading's unit (rad or m).
    terms : dict of str to str
        Term label -> its parameter in ``effect`` (the scale's label is the symbol, the offset's ``1``).
    codes : dict of str to str
        Term label -> its code in a written file (``U0``: the width).
    reach : dict of str to float
        Term label -> the coefficient a written file's bounds cover at least (the term's unit per unit).
    width : str
        The play's width parameter in ``effect`` (rad/s; empty: none).
    """

    group: str
    channel: str
    effect: type[Measurement]
    what: str
    symbol: str
    variable: str
    speed: str
    unit: str
    terms: dict[str, str]
    codes: dict[str, str]
    reach: dict[str, float] = field(default_factory=dict)
    width: str = ""

    @property
    def signature(self) -> str:
        """The residual its reading leaves when it is missing (a written file's ``signature``)."""
        if self.speed:
            return f"a {self.symbol} residual that grows with the angle turned, or changes side where the disc reverses"
        return f"a {self.symbol} residual proportional to {self.symbol}, or constant"

    @property
    def play(self) -> str | None:
        """The label of the play term (None for an LVDT)."""
        return next((lb for lb in self.terms if lb.startswith("tanh")), None)


def _encoder(group: str, channel: str, p: str, what: str, disc: str) -> ReadingSensor:
    sym, speed, play = f"θ{disc}", f"omega_{disc}", f"tanh(ω{disc}/w)"
    return ReadingSensor(
        group, channel, EncoderTerms, what, sym, channel, speed, "rad",
        {sym: f"{p}_scale", "1": f"{p}_offset", play: f"{p}_play"},
        {sym: channel, "1": "1", play: f"math.tanh({speed} / U0)"},
        {sym: 0.05, "1": 0.05, play: 0.05},
        f"{p}_w",
    )  # fmt: skip


def _lvdt(group: str, channel: str, p: str, what: str) -> ReadingSensor:
    var = channel.upper()
    terms, codes = {channel: f"{p}_scale", "1": f"{p}_offset"}, {channel: var, "1": "1"}
    return ReadingSensor(
        group, channel, LvdtTerms, what, channel, var, "", "m", terms, codes, {channel: 0.05, "1": 1e-3}
    )


#: the sensors whose readings are candidates, by the candidate's group
SENSORS = {
    s.group: s
    for s in (
        _encoder("motor_encoder", "theta_u", "me", "the motor encoder", "u"),
        _encoder("lower_encoder", "theta_l", "le", "the lower encoder", "l"),
        _lvdt("lvdt_x", "x", "lx", "the x LVDT"),
        _lvdt("lvdt_y", "y", "ly", "the y LVDT"),
    )
}

#: a term is left out of the words below this size: a scale error (-), an encoder's offset or play (rad: about two
#: counts of an 8000-count encoder, a twist torque of 1e-4 N m; a scale error's fit leaves offsets and plays of
#: 1e-3 rad beside it), an LVDT's offset (m)
_NEGLIGIBLE = {"scale": 1e-4, "rad": 1.5e-3, "m": 1e-6}


def reading_words(group: str, terms: dict[str, float], widths: dict[str, float]) -> str:
    """What a fitted reading says about its sensor, in words.

    Parameters
    ----------
    group : str
        The sensor's group (a key of :data:`SENSORS`).
    terms : dict of str to float
        Term label -> fitted coefficient (the scale: -; the offset and the play: rad or m).
    widths : dict of str to float
        The play's label -> its width (rad/s).

    Returns
    -------
    str
        E.g. ``the lower encoder reads (1 + k) θl with k = +0.0101: its counts per revolution are off by
        +1.01 %``; the terms below their negligible size are left out.
    """
    s = SENSORS[group]
    parts = []
    k = terms.get(s.symbol, 0.0)
    if abs(k) >= _NEGLIGIBLE["scale"]:
        per = "its counts per revolution are" if s.unit == "rad" else "its gain is"
        parts.append(f"{s.what} reads (1 + k) {s.symbol} with k = {k:+.4f}: {per} off by {100 * k:+.2f} %")
    c = terms.get("1", 0.0)
    if abs(c) >= _NEGLIGIBLE[s.unit]:
        size = f"{c:+.4g} rad" if s.unit == "rad" else f"{c * 1e6:+.0f} µm"
        parts.append(f"{s.what} reads {size} off")
    play = s.play
    b = terms.get(play, 0.0) if play else 0.0
    if play and abs(b) >= _NEGLIGIBLE["rad"]:
        w = widths.get(play, float("nan"))
        parts.append(
            f"{s.what}'s shaft leads the disc by {b:+.4g} rad in the direction it turns (free play; it changes "
            f"side over {w:.3g} rad/s)"
        )
    return "; ".join(parts) or f"{s.what} reads {s.symbol} as it is"
