"""CLI: ``identify-staged``, the report's staged identification of the base parameters."""

from __future__ import annotations

from pathlib import Path

import typer

from ..errors import InputError
from .identification import _json
from .options import option, requires
from .outputs import CREATES_DIRS, check_output_file, output_file


def identify_staged_cmd(
    out: Path = typer.Option(..., "--out", help=f"parameter file to write (.json or .yaml); {CREATES_DIRS}"),
    upper: list[Path] = typer.Option([], "--upper", help="recording of the upper part alone"),
    free_vibration: list[Path] = typer.Option([], "--free-vibration", help="free-vibration release test"),
    lower: list[Path] = typer.Option([], "--lower", help="torsional recording with the brake off"),
    lateral: list[Path] = typer.Option([], "--lateral", help="lateral recording (brake off)"),
    brake: list[Path] = typer.Option([], "--brake", help="torsional recordings with the brake (several alpha0)"),
    validate: list[str] = typer.Option([], "--validate", help="STAGE=FILE validation recording (repeatable)"),
    params: Path | None = typer.Option(
        None, "--params", help="initial guesses (default: the identified set, docs/model.md)"
    ),
    as_json: bool = typer.Option(False, "--json", help="print the stages as JSON"),
) -> None:
    """The report's staged identification: upper, free vibration, lower, lateral, brake."""
    from ..identification.staged import STAGES, identify_staged
    from ..io import read_timeseries

    cfg = {
        "upper": "upper",
        "free_vibration": "free_vibration",
        "lower": "torsional",
        "lateral": "lateral",
        "brake": "torsional",
    }
    files = {"upper": upper, "free_vibration": free_vibration, "lower": lower, "lateral": lateral, "brake": brake}
    if out.suffix.lower() not in (".json", ".yaml", ".yml"):
        raise InputError(f"--out {out}: a parameter file must end in .json, .yaml or .yml")
    check_output_file(out, "--out", suffixes=(".json", ".yaml", ".yml"))
    from ..model_files import check_not_model_with_effects

    check_not_model_with_effects(out, "--out")
    if not any(files.values()):
        raise InputError("no recordings given: use --upper, --free-vibration, --lower, --lateral, --brake")

    def stage_recording(stage: str, path: Path, opt: str):
        """A stage's recording, refused when it is of another configuration than the stage fits."""
        with option(opt):
            own = read_timeseries(path)
        want = cfg[stage]
        if own.configuration is not None and own.configuration.label != want:
            raise InputError(
                f"{opt} {path}: a {own.configuration.label} recording; the {stage} stage fits recordings of "
                f"configuration {want}"
            )
        if own.configuration is not None:
            return own
        with option(opt):
            return read_timeseries(path, want)

    data = {k: [stage_recording(k, f, "--" + k.replace("_", "-")) for f in v] for k, v in files.items() if v}
    val: dict = {}
    for item in validate:
        if "=" not in item:
            raise InputError(f"--validate expects STAGE=FILE, got {item!r}")
        k, f = item.split("=", 1)
        if k not in STAGES:
            raise InputError(f"--validate: unknown stage {k!r}; expected one of {', '.join(STAGES)}")
        val.setdefault(k, []).append(stage_recording(k, Path(f), "--validate"))
    from ..params import RigParams

    with option("--params"):
        base_params = RigParams.from_file(params) if params is not None else RigParams()
    res = identify_staged(data, base_params, validation=val)
    res.params.to_file(output_file(out, "--out", suffixes=(".json", ".yaml", ".yml")))
    if as_json:
        typer.echo(_json(res.to_json()))
    else:
        for s in res.stages:
            typer.echo(
                f"stage {s.name}: " + ", ".join(f"{k}={v:.5g}±{s.fit.std[k]:.2g}" for k, v in s.fit.values.items())
            )
            typer.echo(f"  R² estimation {s.r2_estimation}  validation {s.r2_validation}")
            for w in s.fit.warnings:
                typer.echo(f"  warning: {w}")
        typer.echo(f"wrote {out}")


def _validates(stage: str):
    """Whether ``--validate`` values name ``stage`` (STAGE=FILE)."""
    return lambda items: any(str(i).split("=", 1)[0].strip() == stage for i in items or ())


for _stage in ("brake", "lateral", "lower", "free_vibration", "upper"):  # a validation recording of a stage identified
    identify_staged_cmd = requires(
        "--validate",
        "--" + _stage.replace("_", "-"),
        given=_validates(_stage),
        example=f"{_stage}=FILE",
        why=f"{_stage}=FILE validates the {_stage} stage, which only its own recordings identify",
    )(identify_staged_cmd)


def register(app: typer.Typer) -> None:
    """Add the command ``identify-staged``.

    Parameters
    ----------
    app : typer.Typer
        The command-line application.
    """
    app.command("identify-staged")(identify_staged_cmd)
