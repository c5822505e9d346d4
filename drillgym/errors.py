"""Error types a user can fix (bad input); the CLI prints them as one line, exit code 2."""

from __future__ import annotations

from .params import ParameterError


class DataFormatError(ValueError):
    """A time-series file cannot be used: names the file, line/column and what is wrong."""


class SafetyError(RuntimeError):
    """A safety limit of the rig was hit (over-speed, over-displacement, watchdog, lost link)."""


#: printed by the CLI as one line (exit code 2): bad input, and safety stops / lost links of the rig
USER_ERRORS = (ParameterError, DataFormatError, FileNotFoundError, ValueError, SafetyError)
