"""Subcommands of the ``drillgym`` CLI, one module per area.

Each module defines ``register(app: typer.Typer) -> None`` that adds its
commands; :mod:`drillgym.cli` registers every module listed in ``MODULES``
that exists.
"""

MODULES = (
    "drillgym.commands.simulate",
    "drillgym.commands.effects",
    "drillgym.commands.bifurcation",
    "drillgym.commands.identification",
    "drillgym.commands.evaluate",
    "drillgym.commands.train",
    "drillgym.commands.rig",
    "drillgym.commands.params",
    "drillgym.commands.prepare",
)
