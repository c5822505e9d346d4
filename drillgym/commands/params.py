"""``drillgym params``: the parameter set (default: the identified one) with units and sources.

    drillgym params                       print it as YAML, one parameter a line, unit and source as comments
    drillgym params --out params.yaml     write it (.yaml/.yml: commented YAML; .json: values, units, sources)
    drillgym params --params my.yaml --out full.json   a (partial) file completed with the defaults

Every command that reads a parameter file (``--params``) accepts a partial one: the names it
gives override the defaults, unknown names are refused.
"""

from __future__ import annotations

from pathlib import Path

import typer

from ..errors import InputError, MissingFileError
from .options import option
from .outputs import CREATES_DIRS, check_output_file, output_file


def _yaml_float(v: float) -> str:
    """repr of a float that YAML 1.1 (PyYAML) reads back as a float: 1e-06 -> 1.0e-06."""
    r = repr(float(v))
    mant, e, exp = r.partition("e")
    return f"{mant}.0e{exp}" if e and "." not in mant else r


def params_yaml(p) -> str:
    """Commented YAML of a RigParams: ``name: value  # unit; source; meaning``, readable by RigParams.from_file."""
    from ..params import PARAM_INFO, PARAM_NAMES

    lines = [
        "# drillgym parameter set (SI units). A file may give only some names: the others keep",
        "# their default (the identified set of docs/model.md); unknown names are refused.",
        "# Extension parameters (source 'effect ...') are 0 = effect off.",
    ]
    for n in PARAM_NAMES:
        info = PARAM_INFO[n]
        lines.append(f"{n}: {_yaml_float(getattr(p, n))}  # {info['unit']}; {info['source']}; {info['doc']}")
    return "\n".join(lines) + "\n"


def params_json(p) -> str:
    """JSON of a RigParams: ``{"params": {...}, "units": {...}, "sources": {...}, "doc": {...}}``
    (RigParams.from_file reads the ``params`` mapping and ignores the rest)."""
    from ..io.jsonfile import dumps_json
    from ..params import PARAM_INFO

    d = p.to_dict()
    return (
        dumps_json(
            {
                "params": d,
                "units": {n: PARAM_INFO[n]["unit"] for n in d},
                "sources": {n: PARAM_INFO[n]["source"] for n in d},
                "doc": {n: PARAM_INFO[n]["doc"] for n in d},
            },
            indent=2,
        )
        + "\n"
    )


def register(app: typer.Typer) -> None:
    @app.command("params")
    def params_cmd(
        out: Path | None = typer.Option(
            None, "--out", help=f"write to this file (.yaml, .yml or .json) instead of printing; {CREATES_DIRS}"
        ),
        params: Path | None = typer.Option(
            None, "--params", help="start from this (partial) parameter file instead of the identified set"
        ),
    ) -> None:
        """Print or write the parameter set (default: the identified one) with units and sources."""
        from ..params import RigParams

        if out is not None and out.suffix.lower() not in (".json", ".yaml", ".yml"):
            raise InputError(f"--out {out}: a parameter file must end in .json, .yaml or .yml")
        if out is not None:
            check_output_file(out, "--out", suffixes=(".json", ".yaml", ".yml"))
            from ..model_files import check_not_model_with_effects

            check_not_model_with_effects(out, "--out")
        if params is not None and not params.exists():
            raise MissingFileError(f"--params {params}: parameter file not found")
        with option("--params"):
            p = RigParams.from_file(params) if params is not None else RigParams()
        if out is None:
            typer.echo(params_yaml(p), nl=False)
            return
        text = params_json(p) if out.suffix.lower() == ".json" else params_yaml(p)
        output_file(out, "--out", suffixes=(".json", ".yaml", ".yml")).write_text(text, encoding="utf-8")
        typer.echo(
            f"wrote {out} ({len(p.to_dict())} parameters; edit or delete lines: a partial file "
            f"overrides only the names it gives)"
        )
