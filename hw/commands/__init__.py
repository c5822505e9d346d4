"""The hardware twin's commands of the ``drillgym`` CLI: ``drillgym rig emulate | run | tune | estop``.

* :mod:`hw.commands.rig` - the ``rig`` command group (options, messages, exit codes).
* :mod:`hw.commands.tune` - ``rig tune``: an excitation run, diagnose + identify, the model file.
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
    from .tune import tune_cmd

    rig_app.command("tune")(tune_cmd)
    app.add_typer(rig_app, name="rig")
