"""Errors in the options' terms: a refusal found deep in a reader names the option that gave the value.

>>> with option("--params"):
...     RigParams.from_file(path)      # "x.json: unknown parameter(s): who" -> "--params x.json: unknown ..."
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from ..errors import DrillgymError, InputError

__all__ = ["option", "named"]


def named(name: str, exc: DrillgymError) -> DrillgymError:
    """``exc`` with its one-line message led by ``name`` (unchanged when it names it already).

    Parameters
    ----------
    name : str
        The option or argument, e.g. ``"--params"`` or ``"DATA"``.
    exc : DrillgymError
        The refusal.

    Returns
    -------
    DrillgymError
        An error of the same kind (or :class:`~drillgym.errors.InputError` if that kind cannot be
        rebuilt from a message) whose message starts with ``name``.
    """
    message = " ".join(str(exc).split())
    if name in message.split(":", 1)[0] or message.startswith(name):
        return exc
    text = f"{name} {message}" if message.startswith(("/", ".", "~")) else f"{name}: {message}"
    try:
        new = type(exc)(text)
    except Exception:  # a kind with its own constructor
        new = InputError(text)
    return new


@contextmanager
def option(name: str) -> Iterator[None]:
    """Within the block, a :class:`~drillgym.errors.DrillgymError` is re-raised naming ``name``.

    Parameters
    ----------
    name : str
        The option or argument whose value the block reads or checks.

    Raises
    ------
    DrillgymError
        The block's error, its message led by ``name``.
    """
    try:
        yield
    except DrillgymError as exc:
        new = named(name, exc)
        if new is exc:
            raise
        raise new from exc
