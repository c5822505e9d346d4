"""The one rule for what drillgym writes: checked before any work, missing parent directories created.

Every command and function that writes a file (``simulate --out/--plot``, ``params --out``, ``signal OUT``,
``identify --out``, ``identify-staged --out``, ``diagnose --candidate-out``, ``rig run --record``)
or a directory (``compare --out``, ``identify --report``, ``bifurcation --out``, ``evaluate --out``)
checks the path at its start, before any simulation, fit or network call:

* a file path that is a directory, a device, a pipe or a socket is refused;
* an existing file is replaced only when its suffix is one the command writes (``simulate --out
  run.csv`` replaces ``run.csv``; ``simulate --out policy.npz`` never replaces ``policy.npz``);
* a path under a file, or where nothing can be created (``/proc``, a read-only or full file
  system, no permission), is refused;

each in one line naming the option.  The missing directories on the way are created.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterable
from pathlib import Path

from ..errors import OutputPathError
from .paths import create_directory

__all__ = [
    "check_output_file",
    "output_file",
    "output_dir",
    "check_output_dir",
    "figure_file",
    "check_figure_file",
    "check_creatable",
    "check_writable_dir",
    "path_kind",
    "check_not_inputs",
    "check_distinct_outputs",
]


def path_kind(path: Path) -> str:
    """What an existing path is: ``a directory``, ``a file``, ``a device``, ``a pipe``, ``a socket``."""
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISREG(mode):
        return "a file"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_writable_dir(directory: Path, option: str, path: Path | None = None) -> None:
    """Refuse an existing directory that takes no new entry, asked of the file system itself.

    ``os.access`` is not enough: root passes it in ``/proc`` and on read-only mounts, so an entry is
    created and removed.

    Parameters
    ----------
    directory : pathlib.Path
        An existing directory.
    option : str
        The option that named the output, for the message.
    path : pathlib.Path, optional
        The output to be made in ``directory``, for the message. Default: ``directory``.

    Raises
    ------
    OutputPathError
        Nothing can be created in ``directory``.
    """
    where = f"{option} {path if path is not None else directory}"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".drillgym-probe-", dir=directory))
    except OSError as exc:
        raise OutputPathError(f"{where}: cannot create an entry in {directory} ({exc.strerror})") from None


def check_creatable(path: Path, option: str, what: str = "file name") -> None:
    """Refuse a path that does not exist and cannot be created.

    Parameters
    ----------
    path : pathlib.Path
        The path (it does not exist).
    option : str
        The option that named it, for the message.
    what : str, optional
        What to give instead (``"file name"``, ``"directory"``), for the message.

    Raises
    ------
    OutputPathError
        A file among its parents, or the nearest existing parent takes no new entry.
    """
    parent = next((p for p in path.absolute().parents if os.path.lexists(p)), Path("/"))
    if not parent.is_dir():
        raise OutputPathError(
            f"{option} {path}: cannot be created: {parent} is {path_kind(parent)}, not a directory; give a {what}"
        )
    check_writable_dir(parent, option, path)


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
            raise OutputPathError(f"{option} {path} is {path_kind(path)}; give a file name")
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
    check_creatable(path, option, "file name")
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
        check_writable_dir(path, option)
        return path
    check_creatable(path, option, "directory")
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


def check_not_inputs(out: str | Path, option: str, inputs: dict[str, str | Path | None]) -> None:
    """Refuse an output (a file, or a directory a run writes into) that is, or holds, one of the run's inputs.

    A run that writes where it reads (``train --init RUN --out RUN``, ``simulate --input x.csv --out x.csv``)
    replaces what it started from: the input is lost and the record of where the output came from points at
    the output itself.

    Parameters
    ----------
    out : str or path-like
        The output file or directory.
    option : str
        The option that named it, for the message.
    inputs : dict
        The inputs by the option that named them (None: not given).

    Raises
    ------
    OutputPathError
        An input is ``out`` or lies under it.
    """
    target = Path(out).resolve()
    for name, value in inputs.items():
        if value is None or not str(value).strip():
            continue
        p = Path(value).resolve()
        if p == target or target in p.parents:
            raise OutputPathError(
                f"{option} {out} is or holds the {name} ({value}): the run would replace what it reads; choose "
                f"another {option}"
            )


def check_distinct_outputs(files: dict[str, str | Path | None], dirs: dict[str, str | Path | None]) -> None:
    """Refuse two outputs of one run that are one path, or a directory output under a file output.

    Parameters
    ----------
    files : dict
        The file outputs by the option that named them (None: not given).
    dirs : dict
        The directory outputs by the option that named them (None: not given).

    Raises
    ------
    OutputPathError
        Two options name one path (the second write would replace or collide with the first), or a directory
        would lie under a file.
    """
    given = [(o, Path(p).resolve(), True) for o, p in files.items() if p is not None and str(p).strip()]
    given += [(o, Path(p).resolve(), False) for o, p in dirs.items() if p is not None and str(p).strip()]
    for i, (a, pa, a_file) in enumerate(given):
        for b, pb, b_file in given[i + 1 :]:
            if pa == pb:
                raise OutputPathError(f"{a} and {b} name one path ({pa}); give each its own")
            if a_file and pa in pb.parents:
                raise OutputPathError(f"{b} {pb} lies under the file {a} writes ({pa}); give each its own")
            if b_file and pb in pa.parents:
                raise OutputPathError(f"{a} {pa} lies under the file {b} writes ({pb}); give each its own")
