"""The errors drillgym raises on purpose: one hierarchy, rooted at :class:`DrillgymError`.

Every error a user can act on (a bad option, value, file, effect or output path; a safety stop
of the rig; a run or fit that cannot give a valid result) is a :class:`DrillgymError`. The
command line prints these as one line naming what is wrong and exits with code 2 (3 for a
safety stop of ``rig run``). Anything else that escapes is a bug in drillgym: the command line
prints its traceback and says so.

The kinds that describe bad input also derive from :class:`ValueError` (or
:class:`TypeError`), so ``except ValueError`` in user code keeps working.

The kinds, and when they are raised:

* :class:`InputError`: an option, argument or value cannot be used (names it, the value and what would be
  valid).
* :class:`InputTypeError`: the same, for a value of the wrong type.
* :class:`ParameterError`: a rig parameter value or parameter file cannot be used.
* :class:`DataFormatError`: a time-series file cannot be read (file, line or column, what is wrong).
* :class:`EffectError`: an effect cannot be used (file, effect, what is wrong).
* :class:`OutputPathError`: an output path cannot be written without losing something.
* :class:`MissingFileError`: a file the user named does not exist (also a :class:`FileNotFoundError`).
* :class:`SimulationError`: a run diverged or produced non-finite states.
* :class:`FitError`: an identification, a diagnosis or a numerical solve (an equilibrium, a periodic
  orbit) cannot produce its result.
* :class:`UnavailableError`: an optional service (a Ray cluster, a serial port) cannot be reached.
* :class:`SafetyError`: a safety limit of the rig was hit (over-speed, watchdog, lost link).
"""

from __future__ import annotations

__all__ = [
    "DrillgymError",
    "InputError",
    "InputTypeError",
    "ParameterError",
    "DataFormatError",
    "EffectError",
    "OutputPathError",
    "MissingFileError",
    "SimulationError",
    "FitError",
    "FitFailedError",
    "UnavailableError",
    "SafetyError",
]


class DrillgymError(Exception):
    """Base of every error drillgym raises on purpose; the CLI prints it as one line."""


class InputError(DrillgymError, ValueError):
    """An option, argument or value cannot be used: the message names it, the value and what is valid."""


class InputTypeError(InputError, TypeError):
    """An argument of the wrong type: the message names it, the type given and the type expected."""


class ParameterError(InputError):
    """A rig parameter value or parameter file cannot be used."""


class DataFormatError(InputError):
    """A time-series file cannot be used: names the file, line/column and what is wrong."""


class EffectError(InputError):
    """An effect cannot be used: the message names the file, the effect and what is wrong."""


class OutputPathError(InputError):
    """An output path cannot be written without replacing or losing something the user did not ask to."""


class MissingFileError(InputError, FileNotFoundError):
    """A file the user named (an input, a policy, a parameter file, a serial port) does not exist."""


class SimulationError(DrillgymError, RuntimeError):
    """A run diverged or produced non-finite states: names the time and the state."""


class FitError(DrillgymError, RuntimeError):
    """An identification, a diagnosis or a numerical solve cannot produce a valid result (and says why)."""


class FitFailedError(FitError):
    """A fit that could not run or finish, for a reason it names (a non-finite residual at its start, a fitted
    value leaving its physical range): the caller may skip that fit and record the reason; any other exception
    inside a fit is a bug and propagates."""


class UnavailableError(DrillgymError, RuntimeError):
    """An optional service cannot be reached: a Ray cluster, a serial port, a package not installed."""


class SafetyError(DrillgymError, RuntimeError):
    """A safety limit of the rig was hit (over-speed, over-displacement, watchdog, lost link)."""
