"""Lane (SIMD) variants of effect functions: ``math.exp/log/sin/cos`` replaced by drillgym's
vectorisable :mod:`drillgym.vmath` versions, and the power operator with an exponent that is not an
integer literal (``x ** 0.5``, ``(w / ws) ** delta``) by :func:`drillgym.vmath.vpow`, so an effect written
with the math module and ``**`` does not block the vectorisation of the lane kernel (a libm call would).
Other functions are kept."""

from __future__ import annotations

import ast
import inspect
import math
import textwrap
import types
from collections.abc import Callable
from typing import Any

from numba import njit

from ..vmath import FASTMATH, vexp, vlog, vpow, vsincos

__all__ = ["simd_variant", "SIMD_MATH"]


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def _vsin(x: float) -> float:
    return vsincos(x)[0]


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
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
    """A copy of the plain function ``f`` whose globals see vectorisable exp/log/sin/cos and whose powers
    with an exponent other than an integer literal call :func:`drillgym.vmath.vpow`; ``f`` itself when
    there is nothing to replace (or its source cannot be read: then only the globals are replaced)."""
    g = dict(f.__globals__)
    changed = False
    for k, v in f.__globals__.items():
        if v is math:
            g[k] = SIMD_MATH
            changed = True
        elif callable(v) and v in _BY_FUNCTION:
            g[k] = _BY_FUNCTION[v]
            changed = True
    powered = _powers_replaced(f, g)
    if powered is not None:
        return powered
    if not changed:
        return f
    return types.FunctionType(f.__code__, g, f.__name__, f.__defaults__, f.__closure__)


_VPOW = "_drillgym_vpow"


class _Powers(ast.NodeTransformer):
    """``a ** b`` -> ``vpow(a, b)`` unless b is an integer literal (numba multiplies those out)."""

    def __init__(self) -> None:
        self.count = 0

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        exponent = node.right
        integer = isinstance(exponent, ast.Constant) and type(exponent.value) is int
        if not isinstance(node.op, ast.Pow) or integer:
            return node
        self.count += 1
        call = ast.Call(ast.Name(_VPOW, ast.Load()), [node.left, exponent], [])
        return ast.copy_location(call, node)


def _powers_replaced(f: Callable[..., Any], g: dict) -> Callable[..., Any] | None:
    """``f`` compiled again from its source with its powers replaced (:class:`_Powers`) in the globals ``g``;
    None when it has none, or no source, or a closure (then it is kept as written)."""
    if f.__closure__:
        return None
    try:
        source = textwrap.dedent(inspect.getsource(f))
    except (OSError, TypeError):
        return None
    tree = ast.parse(source)
    fn = tree.body[0] if tree.body else None
    if not isinstance(fn, ast.FunctionDef) or fn.name != f.__name__:
        return None
    fn.decorator_list = []
    powers = _Powers()
    powers.visit(tree)
    if not powers.count:
        return None
    ast.fix_missing_locations(tree)
    ast.increment_lineno(tree, f.__code__.co_firstlineno - 1)
    ns = dict(g)
    ns[_VPOW] = vpow
    exec(compile(tree, f.__code__.co_filename, "exec"), ns)
    out = ns[f.__name__]
    out.__defaults__ = f.__defaults__
    return out
