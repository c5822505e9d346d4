"""``drillgym effects``: the effects available by name, with their parameters; ``--show SPEC`` for one
(a name or path/to/file.py:NAME, validated as the simulator would)."""

from __future__ import annotations

import typer

from ..errors import InputError
from .options import option


def _as_dict(cls) -> dict:
    return {
        "name": cls.name,
        "kind": cls.kind,
        "configurations": list(cls.configurations),
        "parameters": [
            {
                "name": p.name,
                "unit": p.unit,
                "lo": p.lo,
                "hi": p.hi,
                "guess": p.guess,
                "scale": p.scale,
                "neutral": p.neutral,
                "doc": p.doc,
            }
            for p in cls.parameters
        ],
        "states": [{"name": s.name, "unit": s.unit, "doc": s.doc} for s in cls.states],
        "order": cls.order_note,
        "explanation": " ".join(cls.explanation.split()),
        "signature": " ".join(cls.signature.split()),
        "source": cls.source_file(),
    }


def register(app: typer.Typer) -> None:
    @app.command("effects")
    def effects_cmd(
        show: str | None = typer.Option(None, "--show", help="one effect: a name or path/to/file.py:NAME"),
        as_json: bool = typer.Option(False, "--json", help="print JSON"),
    ) -> None:
        """List the effects that can be added to the model (library and installed packages), with their
        parameters (unit, bounds, guess); --show validates and describes one, a user file included."""
        from ..effects import available_effects, compose

        if show is not None:
            if not show.strip():
                raise InputError("--show needs one effect: a name (see `drillgym effects`) or path/to/file.py:NAME")
            from ..effects.compile_check import check_compiles

            with option("--show"):
                comp, _ = compose([show])  # validates it exactly as every command would
                check_compiles(comp)  # a body numba cannot compile, refused as the first run would
            classes = list(comp.effects)
        else:
            classes = list(available_effects().values())
        if as_json:
            from ..io.jsonfile import dumps_json

            typer.echo(dumps_json([_as_dict(c) for c in classes], indent=1, nonfinite="refuse"))
            return
        for cls in classes:
            typer.echo(cls.describe())
            typer.echo("")
        if not show:
            typer.echo(
                "add one with --add-effect NAME (or --add-effect path/to/file.py:NAME) and set its parameters "
                "with --effect-param NAME=VALUE; write your own: docs/EFFECTS.md"
            )
