"""``--map COLUMN=NAME``: read a recording's columns under other names (compare, diagnose, identify).

``--map theta_u=enc1`` reads the file's ``enc1`` (CSV column or .mat variable) as ``theta_u``;
``--map theta_u=ScopeData:2`` takes the 2nd column (1-based) of a .mat variable with several
columns (a Simulink "structure with time" whose ``signals.values`` is (N, k), or a matrix).
"""

from __future__ import annotations

from collections.abc import Iterable

from ..errors import InputError

__all__ = ["MAP_HELP", "parse_mapping"]

MAP_HELP = (
    "read a column under another name, COLUMN=NAME (repeatable): theta_u=enc1; a column of a .mat "
    "variable with several: theta_u=ScopeData:2 (1-based)"
)


def parse_mapping(items: Iterable[str]) -> dict[str, str]:
    """{column: file name} from ``COLUMN=NAME`` strings; one-line ValueError for a malformed or repeated one."""
    from ..io import KNOWN_COLUMNS

    out: dict[str, str] = {}
    for item in items:
        col, sep, name = (p.strip() for p in item.partition("="))
        if not sep or not col or not name:
            raise InputError(f"--map {item!r}: expected COLUMN=NAME, e.g. theta_u=enc1")
        if col not in KNOWN_COLUMNS:
            raise InputError(f"--map {item!r}: unknown column {col!r}; expected one of {', '.join(KNOWN_COLUMNS)}")
        if col in out:
            raise InputError(f"--map {item!r}: column {col!r} is mapped twice")
        out[col] = name
    return out
