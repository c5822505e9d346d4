"""Compiled control laws: the controllers' commands as numba code for the compiled closed loop.

A controller that offers one returns a :class:`CompiledLaw` from :meth:`controllers.Controller.compiled_law`
(after its reset): a numba function of :data:`drillgym.closed_loop.LAW_SIGNATURE`, its state started from
the controller's and its constants.  :func:`controllers.evaluation.runner.run_closed_loop` then advances the
plants and the law together in :func:`drillgym.closed_loop.run_compiled_loop`, with no Python call per
control period.  The laws compute what the controllers' ``act`` computes, to round-off (tests compare them).

numba caches the laws next to these files (``cache=True``) keyed on their own source only; they inline the
friction laws and the vectorisable functions of :mod:`drillgym`, so the cached laws are dropped when any of
those sources changed (:func:`invalidate_stale_laws`, at import).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drillgym._kernel_cache import invalidate_stale_kernels, modules_digest

__all__ = ["CompiledLaw", "invalidate_stale_laws"]

_DIR = Path(__file__).resolve().parent
_STAMP = "law_sources.sha256"
#: the drillgym modules whose numba functions the laws inline
_INLINED = ["drillgym.friction", "drillgym.vmath", "drillgym.closed_loop.abi"]


@dataclass(frozen=True)
class CompiledLaw:
    """A controller's law as compiled code (:mod:`drillgym.closed_loop.abi`).

    Attributes
    ----------
    step : numba function
        ``step(t, M, X, C, U)``: one control period of every lane.
    state : ndarray
        The law's state and per-lane constants (rows, n), started from the controller's state.
    constants : ndarray
        Constants shared by the lanes (k,).
    """

    step: object
    state: np.ndarray
    constants: np.ndarray


def _digest() -> str:
    h = hashlib.sha256(modules_digest(_INLINED).encode())
    for f in sorted(_DIR.glob("*.py")):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def invalidate_stale_laws() -> bool:
    """Delete the laws' cached machine code when their sources or the drillgym code they inline changed.

    Returns
    -------
    bool
        True when it did (a read-only installation is left alone).
    """
    return invalidate_stale_kernels(_DIR, _digest(), _STAMP)


invalidate_stale_laws()
