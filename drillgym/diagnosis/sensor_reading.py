"""Candidates the residual torques cannot show: what each sensor reads.

Discovery (:mod:`.discovery`) reads what the model misses from the residual torques, the data's accelerations
against the model's.  A sensor that reads a little off its true value adds no torque: an encoder whose counts per
revolution are off by k reads (1 + k) θ, one with free play between its shaft and the disc (backlash) reads the
shaft, which leads the disc by the play in the direction it turns, an LVDT whose gain is off reads (1 + k) x.
Twice differentiated the play is an impulse the regression cannot fit, and a scale error shows as a twist error
that grows with the angle turned (taken for a friction drift).  Each sensor's reading is therefore a candidate
judged by its own fit only (:func:`.candidate_fit.choose_candidate`): for every measured channel whose final
residual stays above the noise (:data:`.unexplained.EXPLAINED_RATIO`), its reading's terms
(:data:`.reading_terms.SENSORS`, compiled once, every coefficient a parameter) are fitted on the recordings, and
the best reading is kept when it removes more of the unexplained variance than the discovered candidate and at
least :data:`MIN_READING_CUT` of it.  Every reading is fitted: one encoder's scale error reads nearly as the
opposite error of the other with every angle rescaled, which the base parameters freed beside the wrong one take
up (the motor constant and the friction levels 1 % off), so the best is, of those that reach the noise, the one
that moved fewest base parameters, and the least, else the one whose fit removes most.

* An encoder: scale k θ, offset c, play b tanh(ω / w).
* An LVDT (lateral and coupled configurations): scale k x, offset c.

Whether the offset can be seen: every multiple-shooting segment starts from the readings at its start, turned
back into the rig's state through the model's Measurement effects
(:func:`drillgym.identification.sensors.invert_measurement`), so a segment starts exactly on the data whatever the
offset.  An offset common to both
encoders is invisible (only a position-dependent effect, cogging or a position friction, would see the absolute
angle).  An offset of one encoder against the other is not: it shifts the string's twist the segments start
from, a torque kθ c on both discs; it is identifiable as that twist, but not which encoder carries it (the motor
encoder's c reads as the lower's −c), so each encoder's candidate carries it.  An LVDT's offset shifts the disc's
position against the lateral spring and is identifiable as such (the library's ``lvdt_offset``).
"""

from __future__ import annotations

from ..configurations import Configuration
from .reading_terms import SENSORS, ReadingSensor
from .results import Candidate, Diagnosis
from .unexplained import EXPLAINED_RATIO

__all__ = [
    "reading_candidates",
    "reading_candidate",
    "with_fitted_terms",
    "MIN_READING_CUT",
    "START_PLAY_RAD",
    "START_WIDTH_RAD_S",
]

#: where the fit of an encoder's play starts (rad; not 0, where the lead speed has no gradient) and its lead speed
#: (rad/s)
START_PLAY_RAD, START_WIDTH_RAD_S = 0.005, 0.05
#: a reading is kept only when its fit removes at least this share of the unexplained variance (as a discovered
#: candidate must explain :data:`.discovery.MIN_EXPLAINED_SHARE` of the residual torque)
MIN_READING_CUT = 0.3


def reading_candidates(diagnosis: Diagnosis) -> list[Candidate]:
    """Every sensor's reading as a candidate, for the channels the diagnosis leaves above the noise.

    Parameters
    ----------
    diagnosis : Diagnosis
        The diagnosis, with its final residual against the noise (:attr:`~.results.Diagnosis.unexplained`).

    Returns
    -------
    list of Candidate
        One per sensor whose channel's residual is at least :data:`.unexplained.EXPLAINED_RATIO` times its noise
        and that the configuration has, the largest residual first; each with its terms at their start (the
        scale and the offset at 0, an encoder's play at :data:`START_PLAY_RAD` with its lead speed
        :data:`START_WIDTH_RAD_S` as the scanned width, rad/s) and ``explained`` 0 until its fit sets it
        (:func:`with_fitted_terms`).  Empty when the diagnosis has no final model or explains the recording.
    """
    un = diagnosis.unexplained
    if diagnosis.vector is None or un is None or un.explained:
        return []
    label = Configuration(diagnosis.config).label
    found = [
        (un.channels[s.channel], _candidate(s))
        for s in SENSORS.values()
        if un.channels.get(s.channel, 0.0) >= EXPLAINED_RATIO and label in s.effect.configurations
    ]
    return [c for _, c in sorted(found, key=lambda rc: -rc[0])]


def reading_candidate(group: str) -> Candidate:
    """One sensor's reading at its start (``group``: a key of :data:`.reading_terms.SENSORS`).

    Parameters
    ----------
    group : str
        The sensor's candidate group (``lvdt_x``, ``motor_encoder``, ...).

    Returns
    -------
    Candidate
        Its reading as a candidate, unfitted.
    """
    return _candidate(SENSORS[group])


def _candidate(sensor: ReadingSensor) -> Candidate:
    """A sensor's reading at its start: the true value read (the play at :data:`START_PLAY_RAD`)."""
    play = sensor.play
    terms = {lb: (START_PLAY_RAD if lb == play else 0.0) for lb in sensor.terms}
    widths = {play: START_WIDTH_RAD_S} if play else {}
    at_rest = dict.fromkeys(sensor.terms, 0.0)
    return Candidate(sensor.group, terms, dict(sensor.codes), at_rest, 0.0, 0, widths=widths, reach=dict(sensor.reach))


def with_fitted_terms(cand: Candidate) -> Candidate:
    """The reading candidate with its fitted terms and width as its terms (what its file holds as guesses), and
    its fit's variance cut as its ``explained`` share (there is no regression behind it).

    Parameters
    ----------
    cand : Candidate
        A reading candidate (:func:`reading_candidates`), fitted or not.

    Returns
    -------
    Candidate
        The same candidate, updated in place when it has a fit.
    """
    fit = cand.fit
    if fit is None:
        return cand
    sensor = SENSORS[cand.group]
    for label in cand.terms:
        value = fit.values.get(sensor.terms[label])
        if value is not None:
            cand.terms[label] = value
    width = fit.values.get(sensor.width) if sensor.width else None
    if width is not None and sensor.play in cand.widths:
        cand.widths = {sensor.play: width}
    cand.explained = max(fit.variance_cut, 0.0)
    return cand
