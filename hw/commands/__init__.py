"""The hardware twin's commands of the ``drillgym`` CLI: ``drillgym rig emulate | run | estop``.

* :mod:`hw.commands.rig` - the ``rig`` command group (options, messages, exit codes).
* :mod:`hw.commands.rig_ops` - what ``rig run`` does around an episode: dry run, e-stop,
  reconnect, the operator's one-line messages.

The CLI finds :func:`register` through the ``drillgym.commands`` entry-point group
(``pyproject.toml``).
"""

from __future__ import annotations

import typer

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add the ``rig`` command group to the ``drillgym`` application.

    Parameters
    ----------
    app : typer.Typer
        The ``drillgym`` command-line application.
    """
    from .rig import rig_app

    app.add_typer(rig_app, name="rig")
