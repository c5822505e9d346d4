"""Subcommands of the ``drillgym`` CLI, one module per area.

Each command module defines ``register(app: typer.Typer) -> None`` that adds its commands.
:func:`register_commands` adds the core's own modules (:data:`MODULES`), then every
``register`` callable installed in the entry-point group :data:`ENTRY_POINT_GROUP`. The packages
built on the core (``controllers``, ``agents``, ``hw``) bring their commands that way
(``[project.entry-points."drillgym.commands"]`` in ``pyproject.toml``), so the core never
imports them.
"""

from __future__ import annotations

import importlib
import sys
from importlib import metadata
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    import typer

__all__ = ["MODULES", "ENTRY_POINT_GROUP", "register_commands", "command_entry_points"]

#: the core's command modules, registered in this order
MODULES = (
    "drillgym.commands.simulate",
    "drillgym.commands.effects",
    "drillgym.commands.bifurcation",
    "drillgym.commands.signal",
    "drillgym.commands.identification",
    "drillgym.commands.staged",
    "drillgym.commands.params",
    "drillgym.commands.prepare",
)

#: entry-point group of the commands of installed packages (value: a ``register(app)`` callable)
ENTRY_POINT_GROUP = "drillgym.commands"


def command_entry_points() -> list[metadata.EntryPoint]:
    """The installed entry points of :data:`ENTRY_POINT_GROUP`, sorted by name.

    Returns
    -------
    list of importlib.metadata.EntryPoint
        One entry point per command provider; a name installed twice is listed once.
    """
    try:
        eps = metadata.entry_points(group=ENTRY_POINT_GROUP)
    except TypeError:  # pragma: no cover - Python < 3.10 API
        eps = metadata.entry_points().get(ENTRY_POINT_GROUP, [])
    unique = {ep.name: ep for ep in eps}
    return [unique[name] for name in sorted(unique)]


def register_commands(app: typer.Typer) -> None:
    """Add every command to the ``drillgym`` application.

    The core's modules (:data:`MODULES`) come first, then the installed providers of
    :data:`ENTRY_POINT_GROUP` by name. A provider that fails to load is left out with a one-line
    warning on stderr, so one broken package does not take the other commands with it.

    Parameters
    ----------
    app : typer.Typer
        The ``drillgym`` command-line application.
    """
    for name in MODULES:
        importlib.import_module(name).register(app)
    for ep in command_entry_points():
        try:
            register = ep.load()
        except Exception as exc:  # a broken provider: its commands are missing, the others work
            print(f"drillgym: warning: commands {ep.name!r} ({ep.value}) do not load: {exc}", file=sys.stderr)
            continue
        register(app)
