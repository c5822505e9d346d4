"""The one rule for what a command writes: checked before any work, missing parent directories created.

Every command that writes a file (``simulate --out/--plot``, ``params --out``, ``signal OUT``,
``identify --out``, ``identify-staged --out``, ``diagnose --candidate-out``, ``rig run --record``)
or a directory (``compare --out``, ``identify --report``, ``bifurcation --out``, ``evaluate --out``)
checks the path at its start, before any simulation, fit or network call:

* a file path that is a directory, a device, a pipe or a socket is refused;
* an existing file is replaced only when its suffix is one the command writes (``simulate --out
  run.csv`` replaces ``run.csv``; ``simulate --out policy.npz`` never replaces ``policy.npz``);
* a path under a file, or where nothing can be created (``/proc``, a read-only or full file
  system, no permission), is refused;

each in one line naming the option. The missing directories on the way are created, which each
``--help`` says (:data:`CREATES_DIRS`).
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterable
from pathlib import Path

from ..errors import OutputPathError
from ..io import create_directory

__all__ = [
    "CREATES_DIRS",
    "check_output_file",
    "output_file",
    "output_dir",
    "check_output_dir",
    "figure_file",
    "check_figure_file",
]

#: the sentence the --help of every written path ends with
CREATES_DIRS = "missing directories are created"


def _nearest_existing(path: Path) -> Path:
    """The nearest existing ancestor of ``path`` (``path`` itself excluded)."""
    for p in path.parents:
        if p.exists():
            return p
    return Path(".")  # pragma: no cover - a relative path's parents end at '.'


def _kind(path: Path) -> str:
    """What ``path`` is when it is not a regular file or a directory."""
    mode = path.stat().st_mode
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _check_creatable(path: Path, option: str, what: str) -> None:
    """Refuse ``path`` (which does not exist) if it cannot be created: a file among its parents, or the
    nearest existing parent cannot take a new entry (probed by creating one and removing it)."""
    parent = _nearest_existing(path)
    if not parent.is_dir():
        raise OutputPathError(f"{option} {path}: cannot be created: {parent} is a file, not a directory; give a {what}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputPathError(f"{option} {path}: cannot be created: {parent} is not writable")
    try:  # root passes os.access everywhere: ask the file system itself (/proc, read-only mounts)
        probe = tempfile.mkdtemp(prefix=".drillgym-probe-", dir=parent)
    except OSError as exc:
        raise OutputPathError(f"{option} {path}: cannot be created in {parent} ({exc.strerror})") from None
    os.rmdir(probe)


def check_output_file(path: str | Path, option: str = "--out", suffixes: Iterable[str] | None = None) -> Path:
    """Refuse, before any work, an output file that cannot be written or would replace what it should not.

    Nothing is created.

    Parameters
    ----------
    path : str or path-like
        The file a command will write.
    option : str, optional
        The option (or argument) that named it, for the message. Default ``"--out"``.
    suffixes : iterable of str, optional
        The suffixes (lower case, with the dot) of the files this command writes; an existing file
        with another suffix is refused instead of being replaced. Default: any existing regular
        file may be replaced.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputPathError
        If ``path`` is a directory, a device, pipe or socket, an existing file of another kind or
        not writable, or cannot be created (a file among its parents, an unwritable place).
    """
    path = Path(path)
    if not str(path).strip():
        raise OutputPathError(f"{option}: an empty path; give a file name")
    if path.is_dir():
        raise OutputPathError(f"{option} {path} is a directory; give a file name")
    if path.exists():
        if not path.is_file():
            raise OutputPathError(f"{option} {path} is {_kind(path)}; give a file name")
        kinds = tuple(s.lower() for s in suffixes) if suffixes is not None else None
        if kinds is not None and path.suffix.lower() not in kinds:
            raise OutputPathError(
                f"{option} {path} exists and is not a {'/'.join(kinds)} file this command writes: it would be "
                f"replaced; choose another name"
            )
        if not os.access(path, os.W_OK):
            raise OutputPathError(f"{option} {path} exists and is not writable")
        return path
    if path.is_symlink():
        raise OutputPathError(f"{option} {path} is a broken symbolic link; give a file name")
    _check_creatable(path, option, "file name")
    return path


def output_file(path: str | Path, option: str = "--out", suffixes: Iterable[str] | None = None) -> Path:
    """``path`` ready to be written: :func:`check_output_file`, then its missing parent directories created.

    Parameters
    ----------
    path : str or path-like
        The file a command writes.
    option : str, optional
        The option that named it, for the message. Default ``"--out"``.
    suffixes : iterable of str, optional
        See :func:`check_output_file`.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputPathError
        See :func:`check_output_file`.
    """
    path = check_output_file(path, option, suffixes)
    create_directory(path.parent, path)
    return path


def check_output_dir(path: str | Path, option: str = "--out") -> Path:
    """Refuse, before any work, an output directory that cannot be created; create nothing.

    Parameters
    ----------
    path : str or path-like
        The directory a command will write into at its end.
    option : str, optional
        The option that named it, for the message. Default ``"--out"``.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputPathError
        If ``path`` or one of its parents is a file, or no entry can be created in it (or in its
        nearest existing parent).
    """
    path = Path(path)
    if not str(path).strip():
        raise OutputPathError(f"{option}: an empty path; give a directory")
    if path.exists():
        if not path.is_dir():
            raise OutputPathError(f"{option} {path} is a file; give a directory")
        if not os.access(path, os.W_OK | os.X_OK):
            raise OutputPathError(f"{option} {path}: the directory is not writable")
        try:
            os.rmdir(tempfile.mkdtemp(prefix=".drillgym-probe-", dir=path))
        except OSError as exc:
            raise OutputPathError(f"{option} {path}: cannot write in it ({exc.strerror})") from None
        return path
    _check_creatable(path, option, "directory")
    return path


def output_dir(path: str | Path, option: str = "--out") -> Path:
    """The directory ``path``, checked (:func:`check_output_dir`) and created with its missing parents."""
    path = check_output_dir(path, option)
    create_directory(path)
    return path


def check_figure_file(path: str | Path, option: str = "--plot") -> Path:
    """Refuse, before any work, a figure path matplotlib cannot write or that cannot be written; create nothing.

    Parameters
    ----------
    path : str or path-like
        The figure file; its suffix chooses the format (none: png).
    option : str, optional
        The option that named it, for the message. Default ``"--plot"``.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputPathError
        If the suffix is not a format matplotlib writes, or :func:`check_output_file` refuses the path
        (an existing file is replaced only if it is a figure).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(path)
    fmt = path.suffix[1:].lower()
    formats = FigureCanvasAgg.get_supported_filetypes()
    if fmt and fmt not in formats:
        raise OutputPathError(
            f"{option} {path}: a figure cannot be written as .{fmt}; use one of "
            f"{', '.join('.' + f for f in sorted(formats))}"
        )
    return check_output_file(path, option, suffixes=[""] + ["." + f for f in formats])


def figure_file(path: str | Path, option: str = "--plot") -> Path:
    """``path`` ready for a figure: :func:`check_figure_file`, then its missing parent directories created."""
    path = check_figure_file(path, option)
    create_directory(path.parent, path)
    return path
