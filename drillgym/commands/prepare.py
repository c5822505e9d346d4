"""``drillgym prepare``: compile the models ``drillgym diagnose`` and ``drillgym identify`` run into the kernel
cache (``make venv`` does it once per install), so the first identification of a recording is as fast as the
next."""

from __future__ import annotations

import typer


def register(app: typer.Typer) -> None:
    @app.command("prepare")
    def prepare_cmd(
        config: list[str] = typer.Option(
            None,
            "--config",
            help="configuration whose diagnosis models to compile (repeatable; "
            "default: torsional, coupled, lateral, upper)",
        ),
    ) -> None:
        """Compile (or load from the cache) the models `drillgym diagnose` and `drillgym identify` run for
        these configurations: up to a minute each on 2 cores the first time, seconds once cached."""
        from ..configurations import parse_configuration
        from ..prepare import PREPARED_CONFIGS, prepare_identification

        # a wrong name fails before any work
        from .options import option

        with option("--config"):
            names = [parse_configuration(c).label for c in (config or PREPARED_CONFIGS)]
        for name, seconds in prepare_identification(names).items():
            typer.echo(f"{name}: the identification's models compiled and cached ({seconds:.0f} s)")
