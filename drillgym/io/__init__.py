"""Time-series files of the rig (docs/data_format.md): read, validate, write, stream.

One format for measurements, recordings and simulations:

* CSV: ``#`` comment lines first (``# meta: {json}`` holds metadata), then a
  header and comma-separated rows.  Columns in SI units, any order; unknown
  columns are kept.  Required: ``t``, ``u``, ``theta_u``; ``theta_l`` for every
  configuration but ``upper``; ``x``, ``y`` (fixed frame) for ``lateral`` and
  ``coupled``.
* MATLAB ``.mat`` as Simulink writes it (arrays, "structure with time", or
  a timeseries-like struct), columns mapped by name (aliases accepted) or an
  explicit ``mapping={"column": "matlab_name"}``.  A variable with several
  columns (a muxed ``signals.values`` of shape (N, k), several signals of a
  "structure with time", a matrix) offers them as ``name:1`` … ``name:k``
  (1-based, as in MATLAB), e.g. ``mapping={"theta_u": "ScopeData:2"}``; a
  signal's ``label`` is a name too.  The CLI's ``--map theta_u=ScopeData:2``.
* ``mapping`` works for CSV too: ``{"theta_u": "enc1"}`` reads column ``enc1``
  as ``theta_u``.

Every JSON drillgym writes (files, the ``# meta:`` line, printed JSON) goes through
:func:`write_json`/:func:`dumps_json`: strict JSON, no ``NaN`` literal.

A file that cannot be used raises :class:`DataFormatError` naming the file,
the line or column and what is wrong.  Nothing is dropped or guessed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names
from ..errors import DataFormatError
from .limits import KNOWN_COLUMNS, U_LIMIT_FILE, XY_LIMIT_FILE
from .paths import create_directory, describe_parse_error

if TYPE_CHECKING:  # pragma: no cover - loaded on first use (_LAZY)
    from .jsonfile import dumps_json, jsonable, loads_strict, write_json
    from .reading import MAT_ALIASES, read_csv, read_input_signal, read_mat, read_timeseries
    from .timeseries import TimeSeries, required_columns
    from .writing import StreamingCsvWriter, trajectory_to_timeseries, write_timeseries, write_trajectory_csv

#: name -> the module that defines it, imported on first use (PEP 562): the readers and writers load numpy
#: (and scipy for .mat), which the command line's help, quoting the limits above, does not need
_LAZY = {
    **dict.fromkeys(("dumps_json", "jsonable", "loads_strict", "write_json"), "jsonfile"),
    **dict.fromkeys(("MAT_ALIASES", "read_csv", "read_input_signal", "read_mat", "read_timeseries"), "reading"),
    **dict.fromkeys(("TimeSeries", "required_columns"), "timeseries"),
    **dict.fromkeys(
        ("StreamingCsvWriter", "trajectory_to_timeseries", "write_timeseries", "write_trajectory_csv"), "writing"
    ),
}

__all__ = [
    "TimeSeries",
    "read_timeseries",
    "read_input_signal",
    "read_csv",
    "read_mat",
    "write_timeseries",
    "write_trajectory_csv",
    "StreamingCsvWriter",
    "required_columns",
    "DataFormatError",
    "U_LIMIT_FILE",
    "XY_LIMIT_FILE",
    "create_directory",
    "describe_parse_error",
    "trajectory_to_timeseries",
    "KNOWN_COLUMNS",
    "MAT_ALIASES",
    "write_json",
    "dumps_json",
    "loads_strict",
    "jsonable",
]


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
