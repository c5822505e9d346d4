"""CLI: ``compare``, ``diagnose``, ``identify`` (model versus measurements)."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from ..errors import DrillgymError, InputError
from .effect_options import add_effect_option, effect_param_option, trust_option
from .mapping import MAP_HELP, parse_mapping
from .options import named, option, requires
from .outputs import (
    CREATES_DIRS,
    check_distinct_outputs,
    check_figure_file,
    check_output_dir,
    check_output_file,
    figure_file,
    output_file,
)


def _json(obj) -> str:
    """Strict JSON text: a non-finite number (e.g. R² of a constant channel) is written as null and named in
    the object's ``warnings`` list (:func:`drillgym.io.dumps_json`), never as a bare NaN or a silent null."""
    from ..io.jsonfile import dumps_json

    return dumps_json(obj, indent=2)


def _model_file(path: Path | None, trust: bool = False):
    """The model in ``--params`` (base parameters only, or a model file); default the model page's set, no effects."""
    from ..model import Model

    if path is None:
        return Model()
    return Model.load(path, trust=trust)


def _model(path: Path | None, add_effect: list[str] | None, effect_param: list[str] | None, trust: bool = False):
    """(RigParams, composition, effect values, {effect name: spec}) of ``--params`` (its effects) plus
    ``--add-effect``/``--effect-param``; one-line errors name the file, the effect and what is wrong."""
    from .effect_options import compose_named, parse_effect_params

    with option("--params"):
        mf = _model_file(path, trust)
    values = dict(mf.values)
    extra = parse_effect_params(effect_param)
    if extra and not (add_effect or mf.specs):
        raise InputError(f"--effect-param {next(iter(extra))}: no effect in the model (use --add-effect NAME)")
    values.update(extra)
    specs = list(mf.specs) + list(add_effect or [])
    comp, vals = compose_named(specs, values)
    names = {}
    for spec, e in zip(specs, comp.effects):
        names.setdefault(e.name, spec)
    return mf.params, comp, vals, names


#: what ``--segment`` takes, for its help and its message
SEGMENT_HELP = "'auto' (the configuration's default), 'none' (a free run) or a positive number of seconds"


def _segment(value: str) -> float | None:
    """'auto' -> -1 (configuration default), 'none' -> free run, else a positive finite number of seconds."""
    v = value.strip().lower()
    if v == "auto":
        return -1.0
    if v in ("none", "free"):
        return None
    try:
        s = float(v)
    except ValueError:
        raise InputError(f"--segment must be {SEGMENT_HELP}, got {value!r}") from None
    if not (math.isfinite(s) and s > 0):
        raise InputError(f"--segment must be {SEGMENT_HELP}, got {value!r}")
    return s


def _check_segment(seg: float | None, ex) -> None:
    """Refuse a ``--segment`` (s) the recording cannot take (see ``drillgym.identification.segment_length``)."""
    from ..identification.segment_length import segment_length

    segment_length(seg, ex, "--segment", longer_than_recording=False)


def _rate(rate: float) -> float:
    """``--rate`` checked: a positive finite number of Hz."""
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"--rate must be a positive number of Hz, got {rate:g}")
    return rate


def _config(config: str | None):
    """``--config`` parsed (None: the recording's own)."""
    from ..configurations import parse_configuration

    if config is None:
        return None
    with option("--config"):
        return parse_configuration(config)


def _read(data: Path, config: str | None, mapping: list[str] | None, name: str = "DATA"):
    """The recording ``data`` read, a refusal naming ``name``, ``--config`` or ``--map`` as the cause."""
    from ..io import read_timeseries

    cfg = _config(config)
    with option("--map"):
        columns = parse_mapping(mapping or [])
    try:
        own = read_timeseries(data, None, columns)
    except DrillgymError as exc:
        raise named("--map" if columns and "mapping" in str(exc) else name, exc) from exc
    if cfg is None:
        return own
    if own.configuration is not None and own.configuration is not cfg:
        raise InputError(
            f"--config {cfg.label}: {data} is a {own.configuration.label} recording; leave out --config "
            f"or give {own.configuration.label}"
        )
    with option(name):
        return read_timeseries(data, cfg, columns)


def _experiment(data: Path, config: str | None, rate: float, mapping: list[str] | None = None):
    """The recording prepared for comparison on a ``rate`` Hz grid (at most its own sample rate)."""
    import numpy as np

    from ..identification.experiment import prepare_experiment

    _rate(rate)
    ts = _read(data, config, mapping)
    t = np.asarray(ts.t, dtype=float)
    if t.size > 1 and t[-1] > t[0]:
        fs = (t.size - 1) / (t[-1] - t[0])
        if rate > fs * (1 + 1e-6):
            raise InputError(f"--rate {rate:g} Hz is above the recording's sample rate {fs:.6g} Hz; choose <= {fs:.6g}")
    with option("DATA"):
        return prepare_experiment(ts, config, compare_rate_hz=rate)


@requires("--trust", "--model", alternatives=("--params",), why="it trusts the effect files a model file names")
def compare_cmd(
    data: Path = typer.Argument(..., help="recording (csv of docs/data_format.md, or .mat)"),
    params: Path | None = typer.Option(
        None, "--params", help="parameter file, may be partial (default: the identified set, docs/model.md)"
    ),
    config: str | None = typer.Option(None, "--config", help="configuration if the file has none"),
    out: Path = typer.Option(Path("compare_out"), "--out", help=f"output directory; {CREATES_DIRS}"),
    segment: str = typer.Option(
        "none",
        "--segment",
        help="'none': free run from the initial state; a positive number of seconds: re-start from data "
        "every so many seconds (stick-slip); 'auto': 4 s with the brake",
    ),
    rate: float = typer.Option(100.0, help="comparison grid rate (Hz)"),
    add_effect: list[str] = add_effect_option(),
    effect_param: list[str] = effect_param_option(),
    map_: list[str] = typer.Option([], "--map", help=MAP_HELP),
    model_file: Path | None = typer.Option(
        None,
        "--model",
        help="a model file (e.g. from `diagnose --model-out` or `identify`): compared beside the nominal model "
        "(--params, default the identified set), the error of each per channel and in noise units",
    ),
    as_json: bool = typer.Option(False, "--json", help="print the comparison (with --model: of both models) as JSON"),
    trust: bool = trust_option(),
) -> None:
    """Simulate a recording's input from its initial state; R², RMS and where the error lives."""
    from ..diagnosis.compare import compare, write_compare
    from ..diagnosis.screening import default_segment
    from .effect_options import check_effects_act

    check_output_dir(out)
    seg = _segment(segment)
    if model_file is not None and (add_effect or effect_param):
        raise InputError("--model compares the model file as it is: drop --add-effect/--effect-param")
    base, model, values, _ = _model(params, add_effect, effect_param, trust)
    if model_file is not None:
        with option("--model"):
            identified = _model_file(model_file, trust)
    ex = _experiment(data, config, rate, map_)
    check_effects_act(model, ex.config)
    if seg is not None and seg < 0:
        seg = default_segment(ex.config) if ex.config.brake else None
    else:
        _check_segment(seg, ex)
    if model_file is not None:
        from ..diagnosis.model_compare import compare_models, write_model_comparison

        check_effects_act(identified.composition, ex.config, "--model")
        both = compare_models(ex, identified, nominal=base, segment_s=seg)
        paths = write_compare(both.model, out) + write_model_comparison(both, out)
        if as_json:
            typer.echo(_json(both.to_json()))
            return
        typer.echo(both.model.text())
        typer.echo(both.text())
        typer.echo(f"figures and report in {out}/: " + ", ".join(p.name for p in paths))
        return
    comp = compare(ex, base, segment_s=seg, effects=model, effect_params=values)
    paths = write_compare(comp, out)
    if as_json:
        typer.echo(_json(comp.to_json()))
        return
    typer.echo(comp.text())
    typer.echo(f"figures and report in {out}/: " + ", ".join(p.name for p in paths))


#: how a candidate effect file written by ``diagnose`` begins (only such a file is replaced)
CANDIDATE_FILE_HEAD = '"""Candidate effect written by `drillgym diagnose'


def _check_candidate_file(path: Path) -> None:
    """Refuse an existing ``--candidate-out`` that is not a candidate file diagnose wrote (a user's own code)."""
    if not path.is_file():
        return
    try:
        head = path.read_text(encoding="utf-8", errors="replace")[: len(CANDIDATE_FILE_HEAD)]
    except OSError as exc:
        raise InputError(f"--candidate-out {path}: cannot be read ({exc.strerror or exc})") from None
    if head != CANDIDATE_FILE_HEAD:
        raise InputError(
            f"--candidate-out {path}: exists and is not a candidate file diagnose wrote; it is not replaced "
            "(give a new path)"
        )


@requires("--candidate-out", "--sparse", why="the candidate is looked for in the residual torques")
@requires("--trust", "--params", why="it trusts the effect files a model file names")
def diagnose_cmd(
    data: Path = typer.Argument(..., help="recording (csv of docs/data_format.md, or .mat)"),
    params: Path | None = typer.Option(
        None, "--params", help="base parameter file (default: the identified set, docs/model.md)"
    ),
    config: str | None = typer.Option(None, "--config", help="configuration if the file has none"),
    as_json: bool = typer.Option(
        False, "--json", help="print one JSON object: selected, ranking, base_parameters, candidate, ..."
    ),
    segment: str = typer.Option("auto", "--segment", help=f"multiple-shooting segment: {SEGMENT_HELP}"),
    rate: float = typer.Option(50.0, help="comparison grid rate (Hz)"),
    sparse: bool = typer.Option(
        True,
        "--sparse/--no-sparse",
        help="also look for an effect outside the library in the residual torques and the sensors' readings",
    ),
    candidate_out: Path | None = typer.Option(
        None,
        "--candidate-out",
        help="write the candidate effect found in the residual torques or a sensor's reading "
        "to this .py file (default: RECORDING_candidate.py next "
        "to the recording, when one is found)",
    ),
    fixed_base: bool = typer.Option(
        False,
        "--fixed-base",
        help="hold the base parameters (default: re-identify those the recording excites and report which moved)",
    ),
    add_effect: list[str] = add_effect_option(),
    effect_param: list[str] = effect_param_option(),
    candidate: list[str] = typer.Option(
        None,
        "--candidate",
        help="also try this effect (name or path/to/file.py:NAME; repeatable); default candidates: the library's",
    ),
    map_: list[str] = typer.Option([], "--map", help=MAP_HELP),
    trust: bool = trust_option(),
    model_out: Path | None = typer.Option(
        None,
        "--model-out",
        help="write the model selected (base parameters, re-identified ones included, and the effects with "
        f"their fitted values and standard errors) as a model file (.json or .yaml); {CREATES_DIRS}",
    ),
    plot: Path | None = typer.Option(
        None,
        "--plot",
        help="also write a figure (png) of the residual left unexplained: per channel against the noise, the "
        f"phases it concentrates in, and against the quantity it depends on most; {CREATES_DIRS}",
    ),
) -> None:
    """Which SET of effects the recording shows (forward selection with refit, the base parameters
    re-identified alongside), which base parameters moved, and a candidate effect file for what the
    library does not explain; the model is --params with its effects plus --add-effect."""
    from ..diagnosis import DiagnosisOptions, diagnose
    from ..diagnosis.effects import effects_for, get_effect
    from ..diagnosis.reselection import kept_in_turn
    from ..effects import Composition
    from .effect_options import check_effects_act

    if candidate_out is not None and candidate_out.suffix != ".py":
        raise InputError(f"--candidate-out {candidate_out}: the effect file must end in .py")
    if candidate_out is not None:
        check_output_file(candidate_out, "--candidate-out", suffixes=(".py",))
        _check_candidate_file(candidate_out)
    if model_out is not None:
        if model_out.suffix.lower() not in (".json", ".yaml", ".yml"):
            raise InputError(f"--model-out {model_out}: a model file must end in .json, .yaml or .yml")
        check_output_file(model_out, "--model-out", suffixes=(".json", ".yaml", ".yml"))
    if plot is not None:
        check_figure_file(plot)  # its directories created once the diagnosis gave a figure
    check_distinct_outputs({"--candidate-out": candidate_out, "--model-out": model_out, "--plot": plot}, {})
    seg = _segment(segment)
    base, model, values, _ = _model(params, add_effect, effect_param, trust)
    with option("--candidate"):
        extra = [get_effect(c) for c in candidate or []]
    ex = _experiment(data, config, rate, map_)
    check_effects_act(model, ex.config)
    check_effects_act(Composition(tuple(extra)), ex.config, "--candidate")
    if seg is not None and seg > 0:
        _check_segment(seg, ex)
    default_out = data.with_name(data.stem + "_candidate.py")
    if candidate_out is None and default_out.exists():  # replaced only if it is a candidate file diagnose wrote
        check_output_file(default_out, "--candidate-out", suffixes=(".py",))
        _check_candidate_file(default_out)
    cands = None
    if extra:
        cands = effects_for(ex.config) + [e for e in extra if e.name not in {c.name for c in effects_for(ex.config)}]
    options = DiagnosisOptions(
        effects=cands,
        base_effects=model,
        effect_params=values,
        segment_s=seg,
        fixed_base=fixed_base,
        discover=sparse,
        candidate_out=candidate_out or default_out,
        compare_rate_hz=rate,
    )
    found = None
    if model_out is None:
        d = diagnose(ex, base, options=options)
    else:  # the model file: the one identification every route takes (drillgym.identify)
        found = _identify_front(ex, base, model, values, options)
        d = found.diagnosis
        found.model.save(output_file(model_out, "--model-out", suffixes=(".json", ".yaml", ".yml")))
    if plot is not None:
        from ..diagnosis.figure import plot_unexplained

        plot_unexplained(d.unexplained, figure_file(plot), title=data.name)
    if as_json:
        typer.echo(_json(d.to_json()))
    else:
        typer.echo(d.text())
        if d.candidate is not None:
            c = d.candidate
            for line in d.candidate_lines():
                typer.echo(line)
            last = d.final()
            beside = last.selected if last is not d else []
            files = [k.spec for k in kept_in_turn(d)] or [c.effect_file]
            lead = "".join(f"--add-effect {e} " for e in [*beside, *files])
            typer.echo(
                f"  written to {', '.join(f.rsplit(':', 1)[0] for f in files)}; fit it: drillgym identify {data} "
                f"{lead}--out p.json"
            )
        if plot is not None:
            typer.echo(f"wrote {plot}: the residual left unexplained")
        if found is not None:
            for line in found.lines():
                typer.echo(line)
            typer.echo(f"wrote {model_out}: the identified model ({found.model.label})")


def _identify_front(ex, base, model, values, options):
    """:func:`drillgym.identify` with a command's diagnosis settings (the recording as read, its configuration)."""
    from ..identified import IdentifyOptions, identify
    from ..model import Model

    start = Model(base, tuple(model.effects), values) if model.effects or base != type(base)() else None
    return identify(
        ex.recording,
        IdentifyOptions(
            config=ex.config.label,
            start=start,
            discover=options.discover,
            candidate_out=options.candidate_out,
            compare_rate_hz=options.compare_rate_hz,
            fixed_base=options.fixed_base,
            candidates=options.effects,
            segment_s=options.segment_s,
        ),
    )


@requires("--trust", "--params", why="it trusts the effect files a model file names")
def identify_cmd(
    data: Path = typer.Argument(..., help="recording (csv of docs/data_format.md, or .mat)"),
    out: Path = typer.Option(
        ..., "--out", help=f"model file to write (.json or .yaml): params and effects; {CREATES_DIRS}"
    ),
    config: str | None = typer.Option(None, "--config", help="configuration if the file has none"),
    add_effect: list[str] = add_effect_option(),
    effect_param: list[str] = typer.Option(
        None,
        "--effect-param",
        help="starting value of an added effect's parameter (or the value "
        "of one already in --params), NAME=VALUE; repeatable",
    ),
    params: Path | None = typer.Option(
        None,
        "--params",
        help="model file: base parameters, and effects with their values (default: the identified set, no effects)",
    ),
    fit: list[str] = typer.Option(None, "--fit", help="also fit this parameter of the model (repeatable)"),
    refit_base: bool = typer.Option(
        False, "--refit-base", help="also fit the configuration's base parameters with the effects"
    ),
    as_json: bool = typer.Option(False, "--json", help="print r2_before, r2_after, fitted, std, effects as JSON"),
    report: Path | None = typer.Option(
        None, "--report", help="directory for a markdown report with figures; " + CREATES_DIRS
    ),
    segment: str = typer.Option("auto", "--segment", help=f"multiple-shooting segment: {SEGMENT_HELP}"),
    rate: float = typer.Option(50.0, help="comparison grid rate (Hz)"),
    max_nfev: int = typer.Option(30, "--max-nfev", help="least-squares evaluations"),
    map_: list[str] = typer.Option([], "--map", help=MAP_HELP),
    trust: bool = trust_option(),
) -> None:
    """Add effects to the model (library names or your own files) and fit their parameters to a recording;
    with none, refit the configuration's base parameters.  Writes the model (params and effects)."""
    from ..diagnosis import diagnose
    from ..diagnosis.effects import get_effect
    from ..diagnosis.refit import refit
    from ..diagnosis.report import write_report
    from ..diagnosis.screening import default_segment
    from ..effects import compose as compose_effects
    from ..identification.reading_noise import recording_encoders
    from ..model import Model
    from .effect_options import check_effects_act, parse_effect_params

    if out.suffix.lower() not in (".json", ".yaml", ".yml"):
        raise InputError(f"--out {out}: parameter file must end in .json, .yaml or .yml")
    check_output_file(out, "--out", suffixes=(".json", ".yaml", ".yml"))
    if report is not None:
        check_output_dir(report, "--report")
    check_distinct_outputs({"--out": out}, {"--report": report})
    if max_nfev < 1:
        raise InputError(f"--max-nfev must be >= 1, got {max_nfev}")
    seg = _segment(segment)
    added = list(add_effect or [])
    with option("--add-effect"):
        for n in added:
            get_effect(n)  # a one-line error for an unknown effect, before anything runs
    with option("--params"):
        mf = _model_file(params, trust)
        base_comp, base_values = mf.composition, dict(mf.values)
    with option("--add-effect"):
        again = [n for n in (compose_effects(added)[0].names if added else []) if n in base_comp.names]
    if again:
        raise InputError(
            f"--add-effect {again[0]}: the model of --params holds it already; fit its parameters with --fit NAME"
        )
    if not added and not fit and not refit_base:  # the whole identification: drillgym.identify, as every route
        _identify_whole(data, out, config, mf, effect_param, seg, rate, max_nfev, map_, report, as_json)
        return
    starts = parse_effect_params(effect_param)
    held = {k: v for k, v in starts.items() if k in base_values}
    ex = _experiment(data, config, rate, map_)
    with option("--add-effect"):
        check_effects_act(compose_effects(added)[0], ex.config)
    check_effects_act(base_comp, ex.config, "--params")
    if seg is not None and seg < 0:
        seg = default_segment(ex.config)
    else:
        _check_segment(seg, ex)
    try:
        res = refit(
            ex,
            mf.params,
            effects=added,
            effect_params=starts,
            base_effects=base_comp,
            base_values={**base_values, **held},
            fit=list(fit or []),
            refit_base=refit_base,
            segment_s=seg,
            max_nfev=max_nfev,
        )
    except InputError as exc:  # the fit refuses its settings before any evaluation: name the option
        msg = str(exc)
        if any(f"'{f}'" in msg for f in fit or []):
            raise named("--fit", exc) from exc
        if "effect parameter" in msg:
            raise named("--effect-param", exc) from exc
        raise
    encoders = recording_encoders(ex.recording, mf.encoders)  # as identify() reads them
    fitted = Model(res.params, tuple(res.composition.effects), res.effect_values, res.std, encoders=encoders)
    fitted.save(output_file(out, "--out", suffixes=(".json", ".yaml", ".yml")))
    records = fitted.records()
    if report is not None:
        d = diagnose(ex, mf.params, base_effects=base_comp, effect_params=base_values, segment_s=seg)
        write_report(report, ex, mf.params, d, res, seg, base_comp, base_values)
    if as_json:
        typer.echo(
            _json(
                {
                    "r2_before": res.r2_before,
                    "r2_after": res.r2_after,
                    "rms_before": res.rms_before,
                    "rms_after": res.rms_after,
                    "fitted": res.values,
                    "std": res.std,
                    "effects": records,
                    "effects_added": res.effects,
                    "model_before": res.model_before,
                    "params": res.params.to_dict(),
                    "warnings": res.warnings,
                    "out": str(out),
                }
            )
        )
    else:
        typer.echo(f"effects added: {', '.join(res.effects) or 'none (base parameters refitted)'}")
        for k, v in res.values.items():
            sd = res.std.get(k)
            typer.echo(f"  {k} = {v:.6g}" + (f" ± {sd:.2g}" if sd is not None and sd == sd else ""))
        for c in res.r2_before:
            typer.echo(
                f"  {c:<8} R² {res.r2_before[c]:.4f} -> {res.r2_after[c]:.4f}   "
                f"RMS {res.rms_before[c]:.4g} -> {res.rms_after[c]:.4g}"
            )
        for w in res.warnings:
            typer.echo(f"  warning: {w}")
        typer.echo(f"wrote {out}" + (f"; report in {report}/report.md" if report else ""))


def _identify_whole(data, out, config, start, effect_param, seg, rate, max_nfev, map_, report, as_json) -> None:
    """``drillgym identify REC --out FILE`` without effects to add or parameters to fit: :func:`drillgym.identify`
    from the model in ``--params`` (its effects held in the model and refitted), the model file written."""
    from ..diagnosis.report import write_report
    from ..identified import IdentifyOptions, identify
    from .effect_options import parse_effect_params

    values = parse_effect_params(effect_param)
    if values and not start.effects:
        raise InputError(f"--effect-param {next(iter(values))}: no effect in the model (use --add-effect NAME)")
    with option("--effect-param"):
        start = start.replace(values={**start.values, **values}) if values else start
    ex = _experiment(data, config, rate, map_)
    if seg is not None and seg > 0:
        _check_segment(seg, ex)
    found = identify(
        ex.recording,
        IdentifyOptions(
            config=ex.config.label,
            start=start if (start.effects or start.params != type(start.params)()) else None,
            candidate_out=data.with_name(data.stem + "_candidate.py"),
            compare_rate_hz=rate,
            max_nfev=max_nfev,
            segment_s=seg,
        ),
    )
    found.model.save(output_file(out, "--out", suffixes=(".json", ".yaml", ".yml")))
    if report is not None:
        write_report(report, ex, start.params, found.diagnosis, found.fit, seg, start.composition, dict(start.values))
    if as_json:
        res = found.fit
        typer.echo(
            _json(
                {
                    "model": found.model.label,
                    "effects": found.model.records(),
                    "params": found.model.params.to_dict(),
                    "std": dict(found.model.std),
                    "r2_before": res.r2_before,
                    "r2_after": res.r2_after,
                    "rms_before": res.rms_before,
                    "rms_after": res.rms_after,
                    "residual_to_noise": found.residual_to_noise,
                    "candidates": list(found.discovered),
                    "warnings": list(found.warnings),
                    "out": str(out),
                }
            )
        )
        return
    for line in found.lines():
        typer.echo(line)
    for c in found.fit.r2_before:
        typer.echo(
            f"  {c:<8} R² {found.fit.r2_before[c]:.4f} -> {found.fit.r2_after[c]:.4f}   "
            f"RMS {found.fit.rms_before[c]:.4g} -> {found.fit.rms_after[c]:.4g}"
        )
    typer.echo(f"wrote {out}" + (f"; report in {report}/report.md" if report else ""))


def register(app: typer.Typer) -> None:
    """Add the commands ``compare``, ``diagnose`` and ``identify``.

    Parameters
    ----------
    app : typer.Typer
        The command-line application.
    """
    app.command("compare")(compare_cmd)
    app.command("diagnose")(diagnose_cmd)
    app.command("identify")(identify_cmd)
