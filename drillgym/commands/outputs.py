"""The one rule for what a command writes: missing parent directories are created.

Every command that writes a file (``simulate --out/--plot``, ``params --out``, ``signal OUT``,
``identify --out``, ``identify-staged --out``, ``rig run --record``) or a directory
(``compare --out``, ``identify --report``, ``bifurcation --out``) creates the missing
directories on the way and says so in its ``--help`` (:data:`CREATES_DIRS`).  A path that
cannot be created (a file in the way, no permission) is refused in one line.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import OutputPathError
from ..io import create_directory

__all__ = ["CREATES_DIRS", "output_file", "output_dir", "check_output_dir", "figure_file"]

#: the sentence the --help of every written path ends with
CREATES_DIRS = "missing directories are created"


def output_file(path: str | Path) -> Path:
    """``path`` ready to be written: its missing parent directories created; refused if it is a directory."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{path} is a directory; give a file name")
    create_directory(path.parent, path)
    return path


def output_dir(path: str | Path) -> Path:
    """The directory ``path``, created with its missing parents."""
    path = Path(path)
    create_directory(path)
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
        If ``path`` or one of its parents is a file, or the nearest existing parent is not writable.
    """
    path = Path(path)
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"cannot be created: {p} is a file"
                raise OutputPathError(f"{option} {path}: {what}; give a directory")
            if p != path and not os.access(p, os.W_OK | os.X_OK):
                raise OutputPathError(f"{option} {path}: cannot be created: {p} is not writable")
            break
    return path


def figure_file(path: str | Path, option: str = "--plot") -> Path:
    """``path`` ready for a figure: :func:`output_file`, and a format matplotlib can write.

    Parameters
    ----------
    path : str or path-like
        The figure file; its suffix chooses the format (none: png).
    option : str, optional
        The option that named it, for the message. Default ``"--plot"``.

    Returns
    -------
    pathlib.Path
        ``path``, its missing parent directories created.

    Raises
    ------
    OutputPathError
        If the suffix is not a format matplotlib writes, or :func:`output_file` refuses the path.
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
    return output_file(path)
