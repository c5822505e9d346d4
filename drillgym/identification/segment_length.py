"""The multiple-shooting segment length a comparison, a fit or a diagnosis runs with, checked once.

Every path that compares the model with a recording in segments (``compare``, ``refit``, ``diagnose``
and their commands' ``--segment``) takes the same setting:

* ``None``: one free run over the whole recording;
* a negative number: the configuration's default (:func:`default_segment`);
* a positive number of seconds: at least :data:`SEGMENT_MIN_SAMPLES` samples of the comparison grid and
  no longer than the recording.

Anything else (a string, NaN, zero, infinity) is refused in one line naming the setting.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

from ..configurations import Configuration
from ..errors import InputError, InputTypeError
from .experiment import Experiment

__all__ = ["SEGMENT_MIN_SAMPLES", "default_segment", "segment_length"]

#: fewest comparison-grid samples a multiple-shooting segment spans
SEGMENT_MIN_SAMPLES = 10


def default_segment(config: Configuration) -> float:
    """The multiple-shooting segment length (s): 4 s (a few stick-slip cycles) with the brake, 8 s without.

    Parameters
    ----------
    config : Configuration
        The configuration.

    Returns
    -------
    float
        Seconds.
    """
    return 4.0 if config.brake else 8.0


def segment_length(
    segment_s: float | None,
    experiments: Experiment | Sequence[Experiment],
    name: str = "segment_s",
    *,
    longer_than_recording: bool = True,
) -> float | None:
    """The segment length (s) for these experiments, or None for one free run.

    Parameters
    ----------
    segment_s : float or None
        The setting: None (a free run), negative (the configuration's default) or seconds.
    experiments : Experiment or sequence of Experiment
        The recordings compared (one configuration).
    name : str, optional
        The setting's name for the message (``"--segment"`` on the command line).
    longer_than_recording : bool, optional
        Accept a segment longer than a recording (it is then one segment: a free run).  The command line
        refuses it (``False``): the user asked for segments.

    Returns
    -------
    float or None
        Seconds, or None.

    Raises
    ------
    InputTypeError
        ``segment_s`` is not a number (a string, a bool).
    InputError
        NaN, zero or infinite; shorter than :data:`SEGMENT_MIN_SAMPLES` samples of a comparison grid;
        longer than the shortest recording when ``longer_than_recording`` is False.
    """
    if segment_s is None:
        return None
    if isinstance(segment_s, bool) or not isinstance(segment_s, numbers.Real):
        raise InputTypeError(
            f"{name} must be a number of seconds, negative for the configuration's default, or None (one free "
            f"run), got {segment_s!r}"
        )
    exps = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    seg = float(segment_s)
    if not math.isfinite(seg) or seg == 0.0:
        raise InputError(
            f"{name} must be a positive number of seconds, negative for the configuration's default, or None "
            f"(one free run), got {segment_s!r}"
        )
    if seg < 0:
        return default_segment(exps[0].config) if exps else None
    for ex in exps:
        shortest = SEGMENT_MIN_SAMPLES / float(ex.fs)
        if seg < shortest:
            raise InputError(
                f"{name} {seg:g} s spans fewer than {SEGMENT_MIN_SAMPLES} samples of the {ex.fs:g} Hz comparison "
                f"grid: choose >= {shortest:g} s, or a free run (None; --segment none)"
            )
        span = float(ex.t[-1] - ex.t[0]) if len(ex.t) > 1 else 0.0
        if seg > span and not longer_than_recording:
            raise InputError(
                f"{name} {seg:g} s is longer than the recording ({span:g} s): for one free run give None "
                "(--segment none on the command line)"
            )
    return seg
