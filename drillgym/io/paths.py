"""Output files written whole, output directories and parse errors of user files, reported in one line."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from ..errors import OutputPathError


def describe_parse_error(exc: BaseException) -> str:
    """Where and what a YAML or JSON parser found wrong, on one line.

    Parameters
    ----------
    exc : BaseException
        The parser's error (:class:`json.JSONDecodeError`, a ``yaml.YAMLError`` or anything else).

    Returns
    -------
    str
        ``"line L, column C: problem"`` when the parser says where, else its message on one line.
    """
    if isinstance(exc, json.JSONDecodeError):
        return f"line {exc.lineno}, column {exc.colno}: {exc.msg}"
    mark, problem = getattr(exc, "problem_mark", None), getattr(exc, "problem", None)
    if mark is not None and problem:
        context = getattr(exc, "context", None)
        return f"line {mark.line + 1}, column {mark.column + 1}: {problem}" + (f" ({context})" if context else "")
    return " ".join(str(exc).split()) or type(exc).__name__


def create_directory(directory: str | Path, for_path: str | Path | None = None) -> Path:
    """Create ``directory`` and its missing parents (nothing if it exists).

    Parameters
    ----------
    directory : str or path-like
        The directory to create.
    for_path : str or path-like, optional
        The output the directory is made for, named in the message. Default: ``directory``.

    Returns
    -------
    pathlib.Path
        ``directory``.

    Raises
    ------
    OutputPathError
        If a file is in the way or the directory cannot be created (no permission, read-only).
    """
    directory = Path(directory)
    for_path = directory if for_path is None else Path(for_path)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(
            f"{for_path}: cannot create directory {directory}: a file of that name is in the way"
        ) from None
    except OSError as exc:
        raise OutputPathError(f"{for_path}: cannot create directory {directory} ({exc.strerror})") from None
    return directory


def _umask() -> int:
    """The process's file-creation mask (read by setting it back at once)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def written_whole(path: str | Path, what: str, newline: str | None = None) -> Iterator[TextIO]:
    """A text file that replaces ``path`` only once it is complete.

    The text goes to a temporary file beside ``path``, renamed over it when the block ends without an
    error: a full disk or an interruption leaves the old file (or none) and never half a file.  A
    replaced file keeps its permissions; a new one gets the umask's.

    Parameters
    ----------
    path : str or path-like
        The file; replaced if it exists.
    what : str
        What is written, for the message (``"the JSON file"``).
    newline : str, optional
        As :func:`open`'s ``newline``.

    Yields
    ------
    TextIO
        The temporary file, open for writing (UTF-8).

    Raises
    ------
    OutputPathError
        The file cannot be written (a directory of that name, no permission, a full disk).
    """
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{path}: is a directory, cannot write {what} there")
    tmp = None
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent if str(path.parent) else ".")
        with os.fdopen(fd, "w", encoding="utf-8", newline=newline) as fh:
            yield fh
        os.chmod(tmp, path.stat().st_mode & 0o7777 if path.exists() else 0o666 & ~_umask())
        os.replace(tmp, path)
        tmp = None
    except OSError as exc:
        raise OutputPathError(f"{path}: cannot write {what} ({exc.strerror or exc})") from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)
