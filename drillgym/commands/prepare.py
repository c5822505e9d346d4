"""``drillgym prepare``: compile the models ``drillgym diagnose`` runs into the kernel cache (``make venv``
does it once per install), so the first diagnosis of a recording is as fast as the next."""

from __future__ import annotations

from typing import List

import typer


def register(app: typer.Typer) -> None:
    @app.command("prepare")
    def prepare_cmd(
        config: List[str] = typer.Option(["torsional", "coupled"], "--config",
                                         help="configuration whose diagnosis models to compile (repeatable)"),
    ) -> None:
        """Compile (or load from the cache) the search models of `drillgym diagnose` for these
        configurations: about a minute each on 2 cores the first time, seconds once cached."""
        from ..configurations import parse_configuration
        from ..diagnosis.prepare import prepare_diagnosis

        names = [parse_configuration(c).label for c in config]  # a wrong name fails before any work
        for name, seconds in prepare_diagnosis(names).items():
            typer.echo(f"{name}: diagnose's models compiled and cached ({seconds:.0f} s)")
