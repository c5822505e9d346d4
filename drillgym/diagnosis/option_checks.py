"""The settings of a diagnosis, refused at its start when they cannot be right.

:class:`.screening.DiagnosisOptions` runs :func:`check_diagnosis_options` whenever it is made (also by
``dataclasses.replace`` and by :func:`.pipeline.diagnose`'s keyword settings), so the Python API refuses
what the command line refuses, in one line naming the setting, before a recording is read.  What needs
the recording (a segment longer than it, a comparison rate above its sample rate, an effect that does
not act in its configuration) is refused as soon as the recording is prepared
(:func:`.screening.screen`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import InputError, InputTypeError
from ..io.outputs import check_output_file

if TYPE_CHECKING:
    from .refit import RefitOptions
    from .state import DiagnosisOptions

__all__ = ["check_diagnosis_options", "check_refit_options", "as_sequence"]


def as_sequence(name: str, value: Any) -> tuple | None:
    """``value`` as a tuple: one string (an effect, a parameter) is one item, not its characters.

    Parameters
    ----------
    name : str
        The setting, for the message.
    value : any
        None, one string or effect, or an iterable of them.

    Returns
    -------
    tuple or None
        The items; None for None.

    Raises
    ------
    InputTypeError
        ``value`` is neither a string nor iterable (a number).
    """
    if value is None:
        return None
    if isinstance(value, (str, bytes)) or isinstance(value, type):
        return (value,)
    if not hasattr(value, "__iter__"):
        raise InputTypeError(f"{name} must be a name or a sequence of names, got {value!r}")
    return tuple(value)


def _flag(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise InputTypeError(f"{name} must be True or False, got {value!r} of type {type(value).__name__}")


def _count(name: str, value: Any, what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputTypeError(f"{name} must be a whole number ({what}), got {value!r} of type {type(value).__name__}")
    if value < 1:
        raise InputError(f"{name} must be >= 1 ({what}), got {value}")


def _rate(name: str, value: Any, *, none_ok: bool) -> None:
    if value is None and none_ok:
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a number of Hz, got {value!r} of type {type(value).__name__}")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive number of Hz{' or None' if none_ok else ''}, got {value!r}")


def check_diagnosis_options(options: DiagnosisOptions) -> None:
    """Refuse settings of a diagnosis that cannot be right, naming the setting.

    Parameters
    ----------
    options : DiagnosisOptions
        The settings.

    Raises
    ------
    InputTypeError
        A setting of the wrong type (a string for a number, a number for a flag or for the sequence
        ``effects``; one string there is one effect, :func:`as_sequence`).
    InputError
        A rate that is not a positive number of Hz, ``n_joint``, ``max_effects`` or ``max_candidates`` below 1, a
        segment length that is NaN, zero or infinite, an unwritable ``candidate_out``.
    """
    o = options
    _mapping("effect_params", o.effect_params)
    _segment(o.segment_s)
    _rate("compare_rate_hz", o.compare_rate_hz, none_ok=False)
    _rate("lvdt_lowpass_hz", o.lvdt_lowpass_hz, none_ok=True)
    for name in ("refine_speeds", "fixed_base", "discover"):
        _flag(name, getattr(o, name))
    _count("n_joint", o.n_joint, "candidates refitted jointly per round")
    _count("max_effects", o.max_effects, "effects selected at most")
    _count("max_candidates", o.max_candidates, "candidates outside the library found in turn")
    if o.candidate_out is not None:
        if not isinstance(o.candidate_out, (str, Path)):
            raise InputTypeError(f"candidate_out must be a path, got {o.candidate_out!r}")
        if Path(o.candidate_out).suffix != ".py":
            raise InputError(f"candidate_out {o.candidate_out}: the effect file must end in .py")
        check_output_file(o.candidate_out, "candidate_out", suffixes=(".py",))


def check_refit_options(options: RefitOptions) -> None:
    """Refuse settings of a refit that cannot be right, naming the setting.

    Parameters
    ----------
    options : RefitOptions
        The settings.

    Raises
    ------
    InputTypeError
        A setting of the wrong type.
    InputError
        A rate that is not a positive number of Hz, ``max_nfev`` below 1, a segment length that is NaN, zero
        or infinite.
    """
    o = options
    _mapping("effect_params", o.effect_params)
    _mapping("base_values", o.base_values)
    _segment(o.segment_s)
    _rate("compare_rate_hz", o.compare_rate_hz, none_ok=False)
    _flag("refit_base", o.refit_base)
    _count("max_nfev", o.max_nfev, "model evaluations of the fit at most")


def _mapping(name: str, value: Any) -> None:
    if value is not None and not isinstance(value, Mapping):
        raise InputTypeError(f"{name} must be a mapping of name: value, got {value!r}")


def _segment(value: Any) -> None:
    if value is not None and (
        isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value) or value == 0
    ):
        raise InputError(
            f"segment_s must be a positive number of seconds, negative for the configuration's default, or None "
            f"(one free run), got {value!r}"
        )
