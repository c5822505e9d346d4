"""A batch of plants and a compiled control law advancing together: no Python call per control period.

A controller that offers a compiled law (a numba function of :data:`.abi.LAW_SIGNATURE` with its state and
constants) runs here over a whole run: per period the sensors, the law and the plant's compiled kernels,
for all lanes, in one compiled loop specialised per composition of effects (:mod:`.kernel`, a client
template of :mod:`drillgym.effects.codegen`).  The physics core knows no controller: it takes any law of
the signature.
"""

from __future__ import annotations

from .abi import LAW_SIGNATURE, LAW_TYPE, M_REF, M_TL, M_TU, M_X, M_Y, MEASUREMENT_ROWS, N_MEASUREMENTS
from .loop import CHUNK_PERIODS, LoopSignals, run_compiled_loop

__all__ = [
    "LAW_SIGNATURE",
    "LAW_TYPE",
    "MEASUREMENT_ROWS",
    "N_MEASUREMENTS",
    "M_TU",
    "M_TL",
    "M_X",
    "M_Y",
    "M_REF",
    "CHUNK_PERIODS",
    "LoopSignals",
    "run_compiled_loop",
]
