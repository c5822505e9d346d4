"""Lane (SIMD) variants of effect functions: ``math.exp/log/sin/cos`` replaced by drillgym's
vectorisable :mod:`drillgym.vmath` versions, so an effect written with the math module does not
block the vectorisation of the lane kernel (a libm call would).  Other functions are kept."""

from __future__ import annotations

import math
import types
from collections.abc import Callable
from typing import Any

from numba import njit

from ..vmath import vexp, vlog, vsincos

__all__ = ["simd_variant", "SIMD_MATH"]


@njit(inline="always", fastmath=True, error_model="numpy")
def _vsin(x: float) -> float:
    return vsincos(x)[0]


@njit(inline="always", fastmath=True, error_model="numpy")
def _vcos(x: float) -> float:
    return vsincos(x)[1]


_REPLACE = {"exp": vexp, "log": vlog, "sin": _vsin, "cos": _vcos}

#: a stand-in for the math module inside lane variants
SIMD_MATH = types.ModuleType("drillgym_simd_math")
for _name in dir(math):
    if not _name.startswith("_"):
        setattr(SIMD_MATH, _name, getattr(math, _name))
for _name, _f in _REPLACE.items():
    setattr(SIMD_MATH, _name, _f)
_BY_FUNCTION = {getattr(math, n): f for n, f in _REPLACE.items()}


def simd_variant(f: Callable[..., Any]) -> Callable[..., Any]:
    """A copy of the plain function ``f`` whose globals see vectorisable exp/log/sin/cos."""
    g = dict(f.__globals__)
    changed = False
    for k, v in f.__globals__.items():
        if v is math:
            g[k] = SIMD_MATH
            changed = True
        elif callable(v) and v in _BY_FUNCTION:
            g[k] = _BY_FUNCTION[v]
            changed = True
    if not changed:
        return f
    return types.FunctionType(f.__code__, g, f.__name__, f.__defaults__, f.__closure__)
