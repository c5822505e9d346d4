"""The calling convention of a compiled control law: its numba signature and its measurement rows.

A compiled law is a numba function ``law(t, M, X, C, U)`` compiled with :data:`LAW_SIGNATURE`, called
once per control period for the whole batch of n lanes:

* ``t`` (float, s): the time of the period's start since the batch's reset;
* ``M`` (float64 (:data:`N_MEASUREMENTS`, n), C order): what the sensors report this period, one row per
  measurement (:data:`MEASUREMENT_ROWS`: angles in rad after the Measurement effects, quantization and
  noise, LVDT positions in m, targets in rad/s);
* ``X`` (float64 (rows, n), C order): the law's own state and per-lane constants, one row per quantity and
  one column per lane (structure of arrays: loops over the lanes vectorise), updated in place;
* ``C`` (float64 (k,)): constants shared by every lane (gains, matrices, parameters);
* ``U`` (float64 (n,)): receives the command of each lane (V); the loop clips it to the amplifier's range.

Any law of this signature runs in the compiled loop (:mod:`drillgym.closed_loop`), which is compiled
once per composition of effects whatever the law (numba's first-class function type).
"""

from __future__ import annotations

from numba import types

__all__ = ["LAW_SIGNATURE", "LAW_TYPE", "MEASUREMENT_ROWS", "N_MEASUREMENTS", "M_TU", "M_TL", "M_X", "M_Y", "M_REF"]

MEASUREMENT_ROWS = ("theta_u", "theta_l", "x", "y", "omega_ref")
"""Rows of ``M``: motor and lower encoder angles (rad), LVDT x, y in the fixed frame (m), target (rad/s)."""
M_TU, M_TL, M_X, M_Y, M_REF = range(5)
N_MEASUREMENTS = len(MEASUREMENT_ROWS)

_F2 = types.float64[:, ::1]
_F1 = types.float64[::1]
LAW_SIGNATURE = types.void(types.float64, _F2, _F2, _F1, _F1)
"""numba signature of a compiled law: ``law(t, M, X, C, U)`` (module docstring)."""
LAW_TYPE = types.FunctionType(LAW_SIGNATURE)
"""The first-class function type the compiled loop takes a law as."""
