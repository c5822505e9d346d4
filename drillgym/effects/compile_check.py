"""Compiling an effect's functions alone, as the kernels compile them, before the kernels are built.

The kernels call every effect function through numba (nopython mode, ``inline="always"``,
:data:`drillgym.vmath.FASTMATH`; :data:`drillgym.effects.hook_context.JIT`), once as written and once with the math
module's exp/log/sin/cos swapped for vectorisable versions (the lane kernels,
:func:`drillgym.effects.simd.simd_variant`).  A body numba cannot compile (a call of a plain Python helper,
``try``, an import inside the function, ...) would otherwise fail deep inside the first kernel compile
with a long traceback; :func:`check_compiles` compiles each function alone with float arguments, in
about a second, and refuses it in one line naming the file, the effect, the function and numba's reason.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from numba import njit, types
from numba.core.errors import NumbaError, UnsupportedBytecodeError

from .base import Effect, EffectError, Force
from .hook_context import JIT
from .simd import simd_variant

if TYPE_CHECKING:  # pragma: no cover
    from .composition import Composition

__all__ = ["check_compiles", "compile_function", "kernel_functions"]

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_DECORATE = eval(JIT, {"njit": njit})  # noqa: S307 - the kernels' own decorator text, a constant


def kernel_functions(cls: type[Effect]) -> dict[str, Callable[..., Any]]:
    """The functions of an effect the kernels call (a Force's ``torque`` or ``force`` by ``acts_on``)."""
    fns = cls.defined_functions()
    if issubclass(cls, Force):
        need = "force" if cls.acts_on == "lateral" else "torque"
        fns = {k: v for k, v in fns.items() if k in (need, "derivative")}
    return fns


#: the most arguments an effect function may take: CPython compiles a call with more as one built tuple
#: (``CALL_FUNCTION_EX``), which numba cannot inline into the kernels
MAX_ARGUMENTS = 30


def _reason(exc: BaseException, f: Callable[..., Any]) -> str:
    """numba's message in one line: its first informative line, colours and file excerpts left out; the
    common cases in words."""
    text = _ANSI.sub("", str(exc))
    undefined = re.search(r"NameError: name '(\w+)' is not defined", text)
    if undefined and inspect.isfunction(f.__globals__.get(undefined.group(1))):
        return f"it calls {undefined.group(1)}(), a plain Python function: decorate it with @numba.njit"
    if "exception_match" in text:
        return "try/except is not supported"
    if "IMPORT_NAME" in text:
        return "an import inside the function is not supported: import at the top of the file"
    if "closure with *args" in text and f.__code__.co_argcount > MAX_ARGUMENTS:
        return (
            f"it takes {f.__code__.co_argcount} arguments, more than the {MAX_ARGUMENTS} the kernels can pass "
            "(Python passes more as one tuple, which numba does not inline): split it into two effects"
        )
    lines = [ln.strip() for ln in text.splitlines()]
    skip = ("Failed in ", "During:", "File ", "<source", "^", "def ", "return ", "Rejected as", "raised from")
    useful = [ln for ln in lines if ln and not ln.startswith(skip)]
    first = useful[0] if useful else next((ln for ln in lines if ln), type(exc).__name__)
    return re.sub(r"<function (\w+) at 0x[0-9a-f]+>", r"\1", first).rstrip(":. ")


def compile_function(f: Callable[..., Any], n_args: int, lane: bool = False) -> Any:
    """Compile ``f`` as the kernels do (inlined into a caller) for ``n_args`` float64 arguments.

    Parameters
    ----------
    f : callable
        A plain effect function.
    n_args : int
        Its number of arguments.
    lane : bool, optional
        Compile the lane variant (vectorisable exp/log/sin/cos).

    Returns
    -------
    numba dispatcher
        The compiled caller: ``caller(*floats)`` returns what the kernels would get.

    Raises
    ------
    numba.core.errors.NumbaError or numba.core.errors.UnsupportedBytecodeError
        What numba refuses.
    """
    inner = _DECORATE(simd_variant(f) if lane else f)
    names = ", ".join(f"a{i}" for i in range(n_args))
    scope: dict[str, Any] = {"inner": inner}
    exec(f"def caller({names}):\n    return inner({names})\n", scope)  # noqa: S102 - a fixed template
    caller = njit(scope["caller"])
    caller.compile((types.float64,) * n_args)
    return caller


def _returns_numbers(ty: Any, n_out: int) -> bool:
    if n_out == 1:
        return isinstance(ty, (types.Number, types.Boolean))
    return isinstance(ty, types.BaseTuple) and len(ty) == n_out and all(isinstance(t, types.Number) for t in ty)


def _outputs(cls: type[Effect], fn: str) -> int:
    if fn == "derivative":
        return len(cls.states)
    if fn in ("force", "stick"):
        return 2
    if fn == "measure":
        return len(getattr(cls, "channels", ()))
    return 1


def check_effect_compiles(cls: type[Effect]) -> None:
    """Compile every kernel function of ``cls`` alone, as written and as its lane variant.

    Raises
    ------
    EffectError
        One line: the file, the effect, the function and numba's reason (or the type it returns instead
        of a number).
    """
    where = f"{cls.source_file()}: effect {cls.name!r}"
    for fn, f in kernel_functions(cls).items():
        n_args = len(cls.argument_names(fn))
        for lane in (False, True):
            try:
                caller = compile_function(f, n_args, lane)
            except (NumbaError, UnsupportedBytecodeError) as exc:
                raise EffectError(
                    f"{where}: {fn}() cannot be compiled into the kernels (numba, nopython mode): {_reason(exc, f)}; "
                    "docs/EFFECTS.md says what Python an effect function may use"
                ) from None
            ret = caller.nopython_signatures[0].return_type
            if not _returns_numbers(ret, _outputs(cls, fn)):
                hint = "; a path of the function returns nothing" if isinstance(ret, types.Optional) else ""
                raise EffectError(
                    f"{where}: {fn}() returns {ret} when compiled, expected {_outputs(cls, fn)} float(s){hint}"
                )


def check_compiles(comp: Composition) -> None:
    """:func:`check_effect_compiles` for every effect of a composition that is not drillgym's own library."""
    for eff in comp.effects:
        if eff.__module__ != "drillgym.effects.library":
            check_effect_compiles(eff)
