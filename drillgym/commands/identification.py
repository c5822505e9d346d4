"""CLI: ``signal``, ``compare``, ``diagnose``, ``identify``, ``identify-staged`` (model versus measurements)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from .mapping import MAP_HELP, parse_mapping
from .outputs import CREATES_DIRS, output_file


def _json(obj) -> str:
    """JSON text with non-finite numbers (e.g. R² of a constant channel) as null."""
    import math

    def clean(o):
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if isinstance(o, float) and not math.isfinite(o):
            return None
        if hasattr(o, "item") and not isinstance(o, (str, bytes)):
            return clean(o.item())
        return o

    return json.dumps(clean(obj), indent=2)


def _params(path: Optional[Path]):
    from ..params import RigParams

    if path is None:
        return RigParams()
    if not path.exists():
        raise FileNotFoundError(f"{path}: parameter file not found")
    return RigParams.from_file(path)


def _segment(value: str) -> "float | None":
    """'auto' -> -1 (configuration default), 'none'/'0' -> free run, else seconds."""
    v = value.strip().lower()
    if v == "auto":
        return -1.0
    if v in ("none", "0", "free"):
        return None
    try:
        s = float(v)
    except ValueError:
        raise ValueError(f"--segment must be 'auto', 'none' or a number of seconds, got {value!r}") from None
    if s <= 0:
        raise ValueError(f"--segment must be positive, got {value!r}")
    return s


def _experiment(data: Path, config: Optional[str], rate: float, mapping: Optional[List[str]] = None):
    from ..identification.experiment import prepare_experiment
    from ..io import read_timeseries

    return prepare_experiment(read_timeseries(data, config, parse_mapping(mapping or [])), config,
                              compare_rate_hz=rate)


def register(app: typer.Typer) -> None:
    @app.command("signal")
    def signal_cmd(
        out: Path = typer.Argument(..., help=f"output CSV (columns t, u); {CREATES_DIRS}"),
        kind: str = typer.Option("quasi_random", "--kind", help="quasi_random (estimation) or sum_of_sines (validation)"),
        duration: float = typer.Option(60.0, help="duration (s)"),
        rate: float = typer.Option(1000.0, help="sample rate (Hz)"),
        amplitude: float = typer.Option(5.0, help="half range around the offset (V)"),
        offset: float = typer.Option(0.0, help="mean voltage (V)"),
        seed: int = typer.Option(0, help="random seed"),
    ) -> None:
        """Write an excitation signal (the report's estimation/validation inputs) as an input file."""
        from ..signals import quasi_random, sum_of_sines, write_input_file

        gens = {"quasi_random": quasi_random, "sum_of_sines": sum_of_sines}
        if kind not in gens:
            raise ValueError(f"--kind must be one of {', '.join(gens)}, got {kind!r}")
        t, u = gens[kind](duration, rate_hz=rate, seed=seed, amplitude=amplitude, offset=offset)
        write_input_file(output_file(out), t, u, description=f"{kind}, seed {seed}")
        typer.echo(f"wrote {out}: {kind}, {duration:g} s at {rate:g} Hz, u in [{u.min():.2f}, {u.max():.2f}] V")

    @app.command("compare")
    def compare_cmd(
        data: Path = typer.Argument(..., help="recording (DATA_FORMAT csv or .mat)"),
        params: Optional[Path] = typer.Option(None, "--params", help="parameter file, may be partial "
                                                                     "(default MODEL.md set)"),
        config: Optional[str] = typer.Option(None, "--config", help="configuration if the file has none"),
        out: Path = typer.Option(Path("compare_out"), "--out", help=f"output directory; {CREATES_DIRS}"),
        segment: str = typer.Option("none", "--segment",
                                    help="'none': free run from the initial state; seconds: re-start from data "
                                         "every so many seconds (stick-slip); 'auto': 4 s with the brake"),
        rate: float = typer.Option(100.0, help="comparison grid rate (Hz)"),
        map_: List[str] = typer.Option([], "--map", help=MAP_HELP),
    ) -> None:
        """Simulate a recording's input from its initial state; R², RMS and where the error lives."""
        from ..diagnosis.compare import compare, write_compare
        from ..diagnosis.ranking import default_segment

        ex = _experiment(data, config, rate, map_)
        seg = _segment(segment)
        if seg is not None and seg < 0:
            seg = default_segment(ex.config) if ex.config.brake else None
        comp = compare(ex, _params(params), segment_s=seg)
        paths = write_compare(comp, out)
        typer.echo(comp.text())
        typer.echo(f"figures and report in {out}/: " + ", ".join(p.name for p in paths))

    @app.command("diagnose")
    def diagnose_cmd(
        data: Path = typer.Argument(..., help="recording (DATA_FORMAT csv or .mat)"),
        params: Optional[Path] = typer.Option(None, "--params", help="base parameter file (default MODEL.md set)"),
        config: Optional[str] = typer.Option(None, "--config", help="configuration if the file has none"),
        as_json: bool = typer.Option(False, "--json", help="print the ranking as JSON"),
        segment: str = typer.Option("auto", "--segment", help="multiple-shooting segment (s), 'auto' or 'none'"),
        rate: float = typer.Option(50.0, help="comparison grid rate (Hz)"),
        sparse: bool = typer.Option(True, "--sparse/--no-sparse", help="also propose a data-driven term"),
        refit_base: bool = typer.Option(False, "--refit-base", help="lightly refit the base parameters first"),
        map_: List[str] = typer.Option([], "--map", help=MAP_HELP),
    ) -> None:
        """Rank the effect library by how much of the model's residual each effect explains."""
        from ..diagnosis.ranking import diagnose
        from ..diagnosis.sparse import residual_torques, sparse_residual_model

        base = _params(params)
        ex = _experiment(data, config, rate, map_)
        d = diagnose(ex, base, segment_s=_segment(segment), refit_base=refit_base)
        term = None
        if sparse and ex.config is not ex.config.UPPER:
            term = sparse_residual_model(residual_torques(ex, base))
        if as_json:
            out = d.to_json()
            if term is not None:
                out["candidate_term"] = {"expression": term.expression(), "terms": term.terms, "r2": term.r2}
            typer.echo(_json(out))
        else:
            typer.echo(d.text())
            if term is not None:
                typer.echo("data-driven candidate for the residual torque on the lower disc:")
                typer.echo("  " + term.expression())

    @app.command("identify")
    def identify_cmd(
        data: Path = typer.Argument(..., help="recording (DATA_FORMAT csv or .mat)"),
        out: Path = typer.Option(..., "--out", help=f"parameter file to write (.json or .yaml); {CREATES_DIRS}"),
        config: Optional[str] = typer.Option(None, "--config", help="configuration if the file has none"),
        add_effect: List[str] = typer.Option([], "--add-effect", help="effect of the library to add (repeatable)"),
        params: Optional[Path] = typer.Option(None, "--params", help="base parameter file (default MODEL.md set)"),
        as_json: bool = typer.Option(False, "--json", help="print r2_before, r2_after, params as JSON"),
        report: Optional[Path] = typer.Option(None, "--report", help="directory for a markdown report with figures; "
                                                                     + CREATES_DIRS),
        segment: str = typer.Option("auto", "--segment", help="multiple-shooting segment (s), 'auto' or 'none'"),
        rate: float = typer.Option(50.0, help="comparison grid rate (Hz)"),
        map_: List[str] = typer.Option([], "--map", help=MAP_HELP),
    ) -> None:
        """Refit a recording with effects added (or the configuration's base parameters); write the result."""
        from ..diagnosis.effects import get_effect
        from ..diagnosis.ranking import default_segment, diagnose
        from ..diagnosis.refit import refit
        from ..diagnosis.report import write_report

        if out.suffix.lower() not in (".json", ".yaml", ".yml"):
            raise ValueError(f"--out {out}: parameter file must end in .json, .yaml or .yml")
        for n in add_effect:
            get_effect(n)
        base = _params(params)
        ex = _experiment(data, config, rate, map_)
        seg = _segment(segment)
        if seg is not None and seg < 0:
            seg = default_segment(ex.config)
        res = refit(ex, base, effects=add_effect, segment_s=seg)
        res.params.to_file(output_file(out))
        if report is not None:
            d = diagnose(ex, base, segment_s=seg)
            write_report(report, ex, base, d, res, seg)
        if as_json:
            typer.echo(_json({"r2_before": res.r2_before, "r2_after": res.r2_after,
                              "params": res.params.to_dict(), "fitted": res.values, "warnings": res.warnings}))
        else:
            typer.echo(f"effects added: {', '.join(res.effects) or 'none (base parameters refitted)'}")
            for k, v in res.values.items():
                typer.echo(f"  {k} = {v:.6g} ± {res.std.get(k, float('nan')):.2g}")
            for c in res.r2_before:
                typer.echo(f"  {c:<8} R² {res.r2_before[c]:.4f} -> {res.r2_after[c]:.4f}   "
                           f"RMS {res.rms_before[c]:.4g} -> {res.rms_after[c]:.4g}")
            for w in res.warnings:
                typer.echo(f"  warning: {w}")
            typer.echo(f"wrote {out}" + (f"; report in {report}/report.md" if report else ""))

    @app.command("identify-staged")
    def identify_staged_cmd(
        out: Path = typer.Option(..., "--out", help=f"parameter file to write (.json or .yaml); {CREATES_DIRS}"),
        upper: List[Path] = typer.Option([], "--upper", help="recording of the upper part alone"),
        free_vibration: List[Path] = typer.Option([], "--free-vibration", help="free-vibration release test"),
        lower: List[Path] = typer.Option([], "--lower", help="torsional recording with the brake off"),
        lateral: List[Path] = typer.Option([], "--lateral", help="lateral recording (brake off)"),
        brake: List[Path] = typer.Option([], "--brake", help="torsional recordings with the brake (several alpha0)"),
        validate: List[str] = typer.Option([], "--validate", help="STAGE=FILE validation recording (repeatable)"),
        params: Optional[Path] = typer.Option(None, "--params", help="initial guesses (default MODEL.md set)"),
        as_json: bool = typer.Option(False, "--json", help="print the stages as JSON"),
    ) -> None:
        """The report's staged identification: upper, free vibration, lower, lateral, brake."""
        from ..identification.staged import STAGES, identify_staged
        from ..io import read_timeseries

        cfg = {"upper": "upper", "free_vibration": "free_vibration", "lower": "torsional", "lateral": "lateral",
               "brake": "torsional"}
        files = {"upper": upper, "free_vibration": free_vibration, "lower": lower, "lateral": lateral, "brake": brake}
        data = {k: [read_timeseries(f, None if read_timeseries(f).configuration else cfg[k]) for f in v]
                for k, v in files.items() if v}
        if not data:
            raise ValueError("no recordings given: use --upper, --free-vibration, --lower, --lateral, --brake")
        val: dict = {}
        for item in validate:
            if "=" not in item:
                raise ValueError(f"--validate expects STAGE=FILE, got {item!r}")
            k, f = item.split("=", 1)
            if k not in STAGES:
                raise ValueError(f"--validate: unknown stage {k!r}; expected one of {', '.join(STAGES)}")
            val.setdefault(k, []).append(read_timeseries(Path(f), cfg[k]))
        res = identify_staged(data, _params(params), validation=val)
        res.params.to_file(output_file(out))
        if as_json:
            typer.echo(_json(res.to_json()))
        else:
            for s in res.stages:
                typer.echo(f"stage {s.name}: " + ", ".join(f"{k}={v:.5g}±{s.fit.std[k]:.2g}"
                                                           for k, v in s.fit.values.items()))
                typer.echo(f"  R² estimation {s.r2_estimation}  validation {s.r2_validation}")
                for w in s.fit.warnings:
                    typer.echo(f"  warning: {w}")
            typer.echo(f"wrote {out}")
