"""Strict JSON: every JSON text drillgym writes parses with any JSON parser.

Python's :mod:`json` writes ``NaN`` and ``Infinity`` for non-finite floats; those are not JSON, and
most parsers (JavaScript, ``jq``, ``json.loads(..., parse_constant=...)``) refuse them. Every file
and every printed JSON of drillgym goes through :func:`dumps_json` or :func:`write_json`:

* numpy scalars and arrays become numbers and lists, tuples lists, paths strings;
* a non-finite number is never written as a number. With ``nonfinite="warn"`` (the default) it is
  written as ``null`` **and** the top-level object gets a ``"warnings"`` list naming each such
  value ("r2: not a finite number (nan), written as null"), so a null never looks like a result;
  a producer that knows why a value is undefined says so in its own warning first. With
  ``nonfinite="refuse"`` a non-finite number raises :class:`ValueError` (a bug of the producer).
* a value of another type (an object without a JSON form) raises :class:`TypeError` (a bug).

:func:`write_json` writes the file through a temporary file in the same directory, renamed over the
target only once it is complete: a full disk or a killed process never leaves a truncated file, and
an existing file is replaced whole or not at all.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from .paths import written_whole

__all__ = ["jsonable", "dumps_json", "write_json", "loads_strict", "WARNINGS_KEY"]

#: the top-level key listing the values that could not be written as numbers
WARNINGS_KEY = "warnings"


def _name(where: str) -> str:
    return where or "value"


def jsonable(obj: Any, nonfinite: str = "warn", warnings: list[str] | None = None, where: str = "") -> Any:
    """A copy of ``obj`` made of JSON types only (dict, list, str, int, float, bool, None).

    Parameters
    ----------
    obj : object
        Mappings, sequences, numpy arrays and scalars, paths, numbers, strings, None.
    nonfinite : {"warn", "refuse"}, optional
        ``"warn"``: a NaN or infinite number becomes None and a message naming it is appended to
        ``warnings``; ``"refuse"``: it raises :class:`ValueError`.
    warnings : list of str, optional
        Receives the messages of ``"warn"``.
    where : str, optional
        The dotted position of ``obj`` in the whole, for the messages.

    Returns
    -------
    object
        The converted value.

    Raises
    ------
    ValueError
        A non-finite number with ``nonfinite="refuse"``, or an unknown ``nonfinite``.
    TypeError
        A value with no JSON form.
    """
    if nonfinite not in ("warn", "refuse"):
        raise ValueError(f"nonfinite must be 'warn' or 'refuse', got {nonfinite!r}")
    if obj is None or isinstance(obj, (str, bool)):
        return obj
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        if math.isfinite(v):
            return v
        if nonfinite == "refuse":
            raise ValueError(f"{_name(where)} is not a finite number ({v}); JSON has no such number")
        if warnings is not None:
            warnings.append(f"{_name(where)}: not a finite number ({v}), written as null")
        return None
    if isinstance(obj, PurePath):
        return str(obj)
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v, nonfinite, warnings, f"{where}.{k}" if where else str(k)) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, (list, tuple)):
        return [jsonable(v, nonfinite, warnings, f"{where}[{i}]") for i, v in enumerate(obj)]
    raise TypeError(f"{_name(where)}: a {type(obj).__name__} has no JSON form")


def _strict(obj: Any, nonfinite: str) -> Any:
    """``obj`` as JSON types, the warnings of its non-finite numbers added to a top-level mapping."""
    warnings: list[str] = []
    out = jsonable(obj, nonfinite, warnings)
    if warnings:
        if not isinstance(out, dict):
            raise ValueError(f"non-finite numbers outside a JSON object cannot carry a warning: {'; '.join(warnings)}")
        out[WARNINGS_KEY] = list(out.get(WARNINGS_KEY) or []) + warnings
    return out


def dumps_json(obj: Any, *, indent: int | None = None, nonfinite: str = "warn", **kwargs: Any) -> str:
    """JSON text of ``obj`` with no ``NaN``/``Infinity`` literal (see the module's rules).

    Parameters
    ----------
    obj : object
        The value (see :func:`jsonable`).
    indent : int, optional
        Indentation, as :func:`json.dumps`.
    nonfinite : {"warn", "refuse"}, optional
        What becomes of a non-finite number (see :func:`jsonable`).
    **kwargs
        Further arguments of :func:`json.dumps` (``sort_keys``, ``separators``).

    Returns
    -------
    str
        The JSON text.
    """
    return json.dumps(_strict(obj, nonfinite), indent=indent, allow_nan=False, **kwargs)


def write_json(path: str | Path, obj: Any, *, indent: int | None = 2, nonfinite: str = "warn") -> Path:
    """Write ``obj`` as a JSON file (ending with a newline), complete or not at all.

    Parameters
    ----------
    path : str or path-like
        The file; replaced if it exists.
    obj : object
        The value (see :func:`jsonable`).
    indent : int, optional
        Indentation. Default 2.
    nonfinite : {"warn", "refuse"}, optional
        What becomes of a non-finite number (see :func:`jsonable`).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputPathError
        The file cannot be written (a directory of that name, no permission, a full disk).
    """
    text = dumps_json(obj, indent=indent, nonfinite=nonfinite) + "\n"
    with written_whole(path, "the JSON file") as fh:
        fh.write(text)
    return Path(path)


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


def loads_strict(text: str) -> Any:
    """Parse JSON text refusing the ``NaN``/``Infinity``/``-Infinity`` literals Python accepts.

    Parameters
    ----------
    text : str
        The JSON text.

    Returns
    -------
    object
        The parsed value.

    Raises
    ------
    ValueError
        The text is not strict JSON.
    """
    return json.loads(text, parse_constant=_refuse_constant)
