"""What a recording can tell: a verdict about a model needs motion and excitation in the data.

A recording in which the motor's disc does not turn, or whose command never changes while the rig rests,
reproduces any model to its noise: "the base model stands" or "the base model is off" would be claims the
data cannot carry.  :func:`recording_information` measures what the recording holds (its length, how far
each disc turns, how much the command varies); :func:`require_information` refuses, in one line saying what
would tell, a recording that holds too little for a diagnosis or an identification, so no verdict is printed
and no model file is written.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..io import TimeSeries

__all__ = ["CannotTellError", "RecordingInformation", "recording_information", "require_information"]

#: the least span (rad) the motor's disc must turn through for the recording to show the drive's dynamics:
#: about a dozen counts of an 8000-count encoder, far above its noise
MIN_TURN_RAD = 0.01
#: the least span (V) of the command for a recording of a resting rig to excite anything
MIN_INPUT_SPAN_V = 0.05


class CannotTellError(InputError):
    """The recording holds too little to carry a verdict (the message says what would tell)."""


@dataclass(frozen=True)
class RecordingInformation:
    """What a recording holds.

    Attributes
    ----------
    duration_s : float
        Its length (s).
    upper_span_rad, lower_span_rad : float
        How far the motor's (upper) and the lower disc's angles range (rad; NaN: not recorded).
    input_span_v : float
        How far the command ranges (V).
    """

    duration_s: float
    upper_span_rad: float
    lower_span_rad: float
    input_span_v: float

    @property
    def why_not(self) -> str | None:
        """Why no verdict can be drawn from the recording, with what would tell; None when one can."""
        if self.upper_span_rad < MIN_TURN_RAD:
            moved = f"the motor's disc turns through {self.upper_span_rad:.3g} rad in {self.duration_s:.3g} s"
            if self.input_span_v < MIN_INPUT_SPAN_V:
                moved += f" and the command spans {self.input_span_v:.3g} V"
            return (
                f"{moved}: nothing in it depends on the model's dynamics; a recording that turns the discs would "
                "tell (a command above the breakaway, e.g. `drillgym signal` steps or quasi-random input of a few "
                "volts, for tens of seconds)"
            )
        return None


def _span(x: np.ndarray | None) -> float:
    if x is None:
        return float("nan")
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.ptp(x)) if x.size else 0.0


def recording_information(recording: TimeSeries) -> RecordingInformation:
    """Measure what a recording holds (see :class:`RecordingInformation`)."""
    t = np.asarray(recording.t, dtype=float)
    return RecordingInformation(
        duration_s=float(t[-1] - t[0]) if t.size > 1 else 0.0,
        upper_span_rad=_span(recording.theta_u),
        lower_span_rad=_span(recording.theta_l),
        input_span_v=_span(recording.u),
    )


def require_information(recording: TimeSeries) -> RecordingInformation:
    """The recording's information, or a one-line refusal when it cannot carry a verdict.

    Raises
    ------
    CannotTellError
        "cannot tell from this recording: ..." with what would tell.
    """
    info = recording_information(recording)
    why = info.why_not
    if why is not None and recording.theta_u is not None:
        raise CannotTellError(f"cannot tell from this recording ({recording.source}): {why}")
    return info
