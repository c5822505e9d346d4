"""The one number an action carries: the motor voltage, checked for type, shape and finiteness.

Shared by the simulated envs (:class:`drillgym.envs.base.DrillEnv`) and the hardware twin
(``hw/env.py``), so both refuse the same actions with the same one-line message.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import InputError, InputTypeError

__all__ = ["action_voltage"]


def _expected(high: float) -> str:
    return (
        f"a number or an array of shape (1,), e.g. np.array([2.0], dtype=np.float32): one motor voltage "
        f"in the action space Box(-{high:g}, {high:g}, (1,), float32)"
    )


def action_voltage(action: Any, high: float = 5.0) -> float:
    """The action's value (action units: V, or x 5 V when normalised) as a float.

    Parameters
    ----------
    action : float or array_like
        A real number or an array-like of shape (1,) (or 0-d) with a numeric dtype.
    high : float, optional
        The action space's bound, only for the error message.

    Returns
    -------
    float
        The action's value.

    Raises
    ------
    InputTypeError
        None, a string, a boolean or a non-numeric array; the message names what is expected.
    InputError
        Another shape, or a NaN or infinite value.
    """
    if type(action) is np.ndarray and action.shape == (1,) and action.dtype.kind == "f":  # the common case, fast
        v = float(action[0])
    elif isinstance(action, (float, int, np.floating, np.integer)) and not isinstance(action, (bool, np.bool_)):
        v = float(action)
    else:
        if action is None or isinstance(action, (str, bytes, bool, np.bool_)):
            raise InputTypeError(f"action must be {_expected(high)}; got {type(action).__name__} {action!r}")
        try:
            arr = np.asarray(action)
        except Exception:  # noqa: BLE001 - anything numpy cannot read is the wrong type
            raise InputTypeError(f"action must be {_expected(high)}; got {type(action).__name__}") from None
        if arr.dtype.kind not in "iuf":
            raise InputTypeError(
                f"action must be {_expected(high)}; got {type(action).__name__} of dtype {arr.dtype}: {action!r}"
            )
        if arr.shape not in ((1,), ()):
            raise InputError(
                f"action must hold one voltage, shape (1,); got shape {arr.shape}. Expected {_expected(high)}"
            )
        v = float(arr.reshape(-1)[0])
    if not math.isfinite(v):
        raise InputError(f"action (motor voltage) must be finite, got {action!r}")
    return v
