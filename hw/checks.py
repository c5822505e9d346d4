"""Checks of what the hardware commands and classes are given, before any port is opened or file written.

Every check raises one :class:`drillgym.errors.InputError` (or a subclass) whose message names the
option or argument, the value given and what would be valid; the command line prints it as one line
(exit 2).  The same checks guard the Python API (:class:`hw.env.HardwareEnv`, :class:`hw.client.RigClient`,
:class:`hw.emulator.RigEmulator`), so it refuses what the command line refuses.
"""

from __future__ import annotations

import math
import numbers
import os
from pathlib import Path

from drillgym.errors import InputError, InputTypeError, MissingFileError, OutputPathError
from drillgym.io.outputs import check_output_dir, check_output_file, path_kind

__all__ = ["number", "integer", "check_record_path", "check_port"]


def _show(value) -> str:
    """The value as the user wrote it (no numpy repr)."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return f"{float(value):g}" if isinstance(value, float) or hasattr(value, "dtype") else str(value)
    return repr(value)


def number(
    value,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    unit: str = "",
) -> float:
    """``value`` as a finite float within [``low``, ``high``] (``low`` excluded with ``low_open``).

    Parameters
    ----------
    value : object
        What was given.
    name : str
        The option or argument, for the message (``--duration``, ``reply_timeout``).
    low, high : float, optional
        The bounds (inclusive, unless ``low_open``).
    low_open : bool, optional
        Exclude ``low`` itself.
    unit : str, optional
        The unit, for the message.

    Returns
    -------
    float
        The value.

    Raises
    ------
    InputTypeError
        Not a real number.
    InputError
        Not finite or out of range.
    """
    u = f" {unit}" if unit else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputTypeError(f"{name} must be a number{u}, got {_show(value)} ({type(value).__name__})")
    v = float(value)
    if low is None and high is None:
        valid = "a finite number"
    elif high is None:
        valid = f"a finite number {'>' if low_open else '>='} {low:g}{u}"
    elif low is None:
        valid = f"a finite number <= {high:g}{u}"
    else:
        valid = f"in {'(' if low_open else '['}{low:g}, {high:g}]{u}"
    ok = math.isfinite(v)
    ok = ok and (low is None or (v > low if low_open else v >= low)) and (high is None or v <= high)
    if not ok:
        raise InputError(f"{name} must be {valid}, got {_show(value)}")
    return v


def integer(value, name: str, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int within [``low``, ``high``]; InputTypeError for a non-integer, InputError out of range."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputTypeError(f"{name} must be an integer, got {_show(value)} ({type(value).__name__})")
    v = int(value)
    if (low is not None and v < low) or (high is not None and v > high):
        rng = f">= {low}" if high is None else f"<= {high}" if low is None else f"in [{low}, {high}]"
        raise InputError(f"{name} must be an integer {rng}, got {v}")
    return v


def check_record_path(record, option: str = "--record") -> Path:
    """Refuse, before any port is opened, a recording path that cannot be written; nothing is created.

    A ``.csv`` path is the first episode's file (an existing regular file is replaced, as the option says; later
    episodes go to ``<stem>_001.csv``, ...); any other path is a directory the episodes are written into.

    Parameters
    ----------
    record : str or path
        The recording path.
    option : str, optional
        The option or argument that named it, for the message.

    Returns
    -------
    pathlib.Path
        The path.

    Raises
    ------
    OutputPathError
        An empty path; a ``.csv`` path that is a directory, a device, a pipe or a socket, or an unwritable file; a
        directory path that is a file; a path that cannot be created (under a file, in ``/proc``, no permission).
    """
    if isinstance(record, bool) or not isinstance(record, (str, os.PathLike)):
        raise InputTypeError(f"{option} must be a path, got {_show(record)} ({type(record).__name__})")
    p = Path(record)
    if not str(record).strip():
        raise OutputPathError(f"{option}: an empty path; give a .csv file or a directory")
    if p.suffix.lower() == ".csv":
        return check_output_file(p, option, suffixes=[".csv"])
    if p.exists() and not p.is_dir():
        raise OutputPathError(
            f"{option} {p} is {path_kind(p)}; give a directory for the recordings, or a file name ending in .csv"
        )
    return check_output_dir(p, option)


def check_port(port, option: str = "--port") -> str:
    """Refuse a serial port that cannot be one: not a string, empty, missing, a directory, a regular file, a pipe.

    pyserial URLs (``socket://``, ``loop://``, ``rfc2217://``) are left to pyserial.

    Parameters
    ----------
    port : str
        Device path or pyserial URL.
    option : str, optional
        The option or argument that named it, for the message.

    Returns
    -------
    str
        The port.

    Raises
    ------
    MissingFileError
        The device does not exist.
    InputError
        Not a character device (a terminal or serial adapter).
    """
    if isinstance(port, bool) or not isinstance(port, (str, os.PathLike)):
        raise InputTypeError(f"{option} must be a device path or a pyserial URL, got {_show(port)}")
    port = os.fspath(port)
    if not port.strip():
        raise InputError(f"{option}: an empty device path; give the rig's serial device or a pyserial URL")
    if "://" in port:
        return port
    if not os.path.exists(port):
        raise MissingFileError(
            f"{option} {port} does not exist (no such serial device: is the rig plugged in, or `drillgym rig emulate` "
            "running?)"
        )
    kind = path_kind(Path(port))
    if kind != "a device":
        raise InputError(
            f"{option} {port} is {kind}, not a serial device: give the rig's device (e.g. /dev/ttyUSB0), the link "
            "`drillgym rig emulate --port` made, or a pyserial URL"
        )
    return port
