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
import stat
import tempfile
from pathlib import Path

from drillgym.errors import InputError, InputTypeError, MissingFileError, OutputPathError

__all__ = ["number", "integer", "check_record_path", "check_port", "check_creatable", "describe_kind"]


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


def describe_kind(path: Path) -> str:
    """What an existing path is: ``a directory``, ``a regular file``, ``a device``, ``a pipe``, ``a socket``."""
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISREG(mode):
        return "a regular file"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_creatable(path: Path, option: str, what: str = "file") -> None:
    """Refuse a path that does not exist and cannot be created: a file among its parents, or a nearest existing
    directory that takes no new entry (asked of the file system itself: root passes ``os.access`` in ``/proc``).

    Parameters
    ----------
    path : pathlib.Path
        The path (it does not exist).
    option : str
        The option that named it, for the message.
    what : str, optional
        ``file`` or ``directory``, for the message.

    Raises
    ------
    OutputPathError
        It cannot be created.
    """
    parent = next((p for p in path.absolute().parents if os.path.lexists(p)), Path("/"))
    if not parent.is_dir():
        raise OutputPathError(
            f"{option} {path}: cannot be created: {parent} is {describe_kind(parent)}, not a directory"
        )
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".drillgym-probe-", dir=parent))
    except OSError as exc:
        raise OutputPathError(f"{option} {path}: cannot create a {what} in {parent} ({exc.strerror})") from None


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
        if p.exists():
            kind = describe_kind(p)
            if kind != "a regular file":
                raise OutputPathError(
                    f"{option} {p} is {kind}; give a .csv file name (or a directory path without the .csv suffix)"
                )
            if not os.access(p, os.W_OK):
                raise OutputPathError(f"{option} {p} exists and is not writable")
            return p
        if p.is_symlink():
            raise OutputPathError(f"{option} {p} is a broken symbolic link; give a .csv file name")
        check_creatable(p, option, "file")
        return p
    if p.exists():
        kind = describe_kind(p)
        if kind != "a directory":
            raise OutputPathError(
                f"{option} {p} is {kind}; give a directory for the recordings, or a file name ending in .csv"
            )
        try:
            os.rmdir(tempfile.mkdtemp(prefix=".drillgym-probe-", dir=p))
        except OSError as exc:
            raise OutputPathError(f"{option} {p}: cannot write in the directory ({exc.strerror})") from None
        return p
    check_creatable(p, option, "directory")
    return p


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
    kind = describe_kind(Path(port))
    if kind != "a device":
        raise InputError(
            f"{option} {port} is {kind}, not a serial device: give the rig's device (e.g. /dev/ttyUSB0), the link "
            "`drillgym rig emulate --port` made, or a pyserial URL"
        )
    return port
