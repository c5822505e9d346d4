"""The one rule for what a command writes: missing parent directories are created.

Every command that writes a file (``simulate --out/--plot``, ``params --out``, ``signal OUT``,
``identify --out``, ``identify-staged --out``, ``rig run --record``) or a directory
(``compare --out``, ``identify --report``, ``bifurcation --out``) creates the missing
directories on the way and says so in its ``--help`` (:data:`CREATES_DIRS`).  A path that
cannot be created (a file in the way, no permission) is refused in one line.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import OutputPathError

__all__ = ["CREATES_DIRS", "output_file", "output_dir"]

#: the sentence the --help of every written path ends with
CREATES_DIRS = "missing directories are created"


def _mkdir(directory: Path, for_path: Path) -> None:
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OutputPathError(f"{for_path}: cannot create directory {directory}: a file of that name is in the way") \
            from None
    except OSError as exc:
        raise OutputPathError(f"{for_path}: cannot create directory {directory} ({exc.strerror})") from None


def output_file(path: str | Path) -> Path:
    """``path`` ready to be written: its missing parent directories created; refused if it is a directory."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{path} is a directory; give a file name")
    _mkdir(path.parent, path)
    return path


def output_dir(path: str | Path) -> Path:
    """The directory ``path``, created with its missing parents."""
    path = Path(path)
    _mkdir(path, path)
    return path
