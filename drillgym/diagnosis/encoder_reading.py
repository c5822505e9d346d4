"""A candidate the residual torques cannot show: the motor encoder reading the motor's shaft, not the disc.

Discovery (:mod:`.discovery`) reads what the model misses from the residual torques, the data's accelerations
against the model's.  Free play between the motor's shaft, which carries the encoder, and the upper disc it drives
(backlash) changes mostly what the encoder reads: the shaft leads the disc by the play in the direction it turns,
so the reading is off by about ±b and changes side where the disc reverses.  Twice differentiated, that step is
an impulse the regression cannot fit.  The candidate is therefore judged by its own fit only
(:func:`.candidate_fit.choose_candidate`): the encoder's reading θu + b tanh(ωu / w)
(:class:`.motor_terms.MotorEncoderTerms`) fitted on the recordings, kept when it removes more of the unexplained
variance than the discovered candidate and at least :data:`MIN_READING_CUT` of it.
"""

from __future__ import annotations

from .motor_terms import ENCODER_TERM, WIDTH_PARAMETERS, term_parameters
from .results import Candidate, Diagnosis
from .unexplained import EXPLAINED_RATIO

__all__ = ["reading_candidate", "with_fitted_terms", "MIN_READING_CUT", "START_PLAY_RAD", "START_WIDTH_RAD_S"]

#: where the fit of the play starts (rad; not 0, where the lead speed has no gradient) and its lead speed (rad/s)
START_PLAY_RAD, START_WIDTH_RAD_S = 0.005, 0.05
#: the reading is kept only when its fit removes at least this share of the unexplained variance (as a discovered
#: candidate must explain :data:`.discovery.MIN_EXPLAINED_SHARE` of the residual torque)
MIN_READING_CUT = 0.3


def reading_candidate(diagnosis: Diagnosis) -> Candidate | None:
    """The motor encoder's reading as a candidate, or None when the diagnosis leaves the motor encoder's channel at
    the noise (or has no final model).

    Parameters
    ----------
    diagnosis : Diagnosis
        The diagnosis, with its final residual against the noise (:attr:`~.results.Diagnosis.unexplained`).

    Returns
    -------
    Candidate or None
        Group ``motor_encoder``, one term (the play, rad) with its lead speed as the scanned width (rad/s); its
        ``explained`` is 0 until its fit sets it (:func:`with_fitted_terms`).
    """
    un = diagnosis.unexplained
    if diagnosis.vector is None or un is None or un.explained:
        return None
    if un.channels.get("theta_u", 0.0) < EXPLAINED_RATIO:
        return None
    return Candidate(
        "motor_encoder",
        {ENCODER_TERM: START_PLAY_RAD},
        {ENCODER_TERM: "math.tanh(omega_u / U0)"},
        {ENCODER_TERM: 0.0},
        0.0,
        0,
        widths={ENCODER_TERM: START_WIDTH_RAD_S},
        reach={ENCODER_TERM: 0.05},
    )


def with_fitted_terms(cand: Candidate) -> Candidate:
    """The reading candidate with its fitted play and lead speed as its terms (what its file holds as guesses), and
    its fit's variance cut as its ``explained`` share (there is no regression behind it)."""
    fit = cand.fit
    if fit is None:
        return cand
    play = fit.values.get(term_parameters("motor_encoder", ENCODER_TERM))
    width = fit.values.get(WIDTH_PARAMETERS["motor_encoder"])
    if play is not None:
        cand.terms = {ENCODER_TERM: play}
    if width is not None:
        cand.widths = {ENCODER_TERM: width}
    cand.explained = max(fit.variance_cut, 0.0)
    return cand
