"""The time-series format's limits and column names: plain constants, without numpy, so that the
command line's help and option checks quote them without loading the readers (docs/data_format.md)."""

from __future__ import annotations

__all__ = ["U_LIMIT_FILE", "XY_LIMIT_FILE", "KNOWN_COLUMNS"]

U_LIMIT_FILE = 50.0  # V: larger |u| in a file is refused
XY_LIMIT_FILE = 0.05  # m: larger |x|, |y| in a file is refused
KNOWN_COLUMNS = ("t", "u", "theta_u", "theta_l", "x", "y", "omega_u", "omega_l")
