"""Output directories and parse errors of user files, reported in one line."""

from __future__ import annotations

import json
from pathlib import Path

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
