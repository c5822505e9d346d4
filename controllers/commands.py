"""The controllers' command of the ``drillgym`` CLI: ``evaluate``.

``drillgym evaluate`` runs controllers (and trained agents, ``agent:PATH``) on the evaluation
harness. ``--add-effect``/``--effect-param`` give the plant hidden effects; the controllers are
built from the nominal base parameters and never know them, or on ``--model FILE`` (a model file:
base parameters and effects, e.g. written by ``identify --out`` or ``diagnose --model-out``), whose
effects ``observer``, ``lqg`` and ``lqg-2enc`` run and the others leave (their base parameters only).

The CLI finds :func:`register` through the ``drillgym.commands`` entry-point group
(``pyproject.toml``).
"""

from __future__ import annotations

import warnings
from contextlib import nullcontext
from pathlib import Path

import typer

from drillgym.commands.effect_options import add_effect_option, effect_param_option, trust_option
from drillgym.commands.options import excludes, requires
from drillgym.errors import InputError


def _has_plants(scenarios: str) -> bool:
    """Whether the ``--scenarios`` list holds the population of plants."""
    return "plants" in [s.strip() for s in scenarios.split(",")]


def register(app: typer.Typer) -> None:
    """Add ``evaluate`` to the ``drillgym`` application.

    Parameters
    ----------
    app : typer.Typer
        The ``drillgym`` command-line application.
    """

    @app.command("evaluate")
    @requires("--excitation", "--identify", why="the length of each plant's excitation run")
    @requires("--identify", "--scenarios", when=_has_plants, what="--scenarios plants", why="it identifies each plant")
    @requires("--uncertainty", "--scenarios", when=_has_plants, what="--scenarios plants")
    @requires("--plants", "--scenarios", when=_has_plants, what="--scenarios plants")
    @requires("--plants-file", "--scenarios", when=_has_plants, what="--scenarios plants")
    @excludes("--plants-file", "--plants", why="the file lists the plants")
    @excludes("--plants-file", "--uncertainty", why="the file lists the plants; nothing is drawn")
    @excludes("--model", "--identify", why="--identify builds the controllers on each plant's identified model")
    @requires(
        "--trust",
        "--model",
        alternatives=("--params", "--plants-file"),
        why="it trusts the effect files a model file names",
    )
    def evaluate_cmd(
        config: str = typer.Option("torsional,coupled", "--config", help="configuration(s), comma-separated"),
        controllers: str = typer.Option(
            "baseline,pi,softtorque,observer",
            "--controllers",
            help="comma-separated: baseline, pi, softtorque, observer, lqg, agent:PATH; "
            "NAME@MS sets the control period, e.g. observer@10",
        ),
        out: Path = typer.Option(
            ..., "--out", help="output directory (results.csv, summary.md, figure); missing directories are created"
        ),
        scenarios: str = typer.Option(
            "rest",
            "--scenarios",
            help="comma-separated: rest, cycle, friction-20, friction+20, noisy, plants "
            "(a population of plants drawn from --uncertainty, or listed in --plants-file)",
        ),
        plants: int | None = typer.Option(
            None, "--plants", help="number of plants the 'plants' scenario draws from --uncertainty; default 20"
        ),
        plants_file: Path = typer.Option(
            None,
            "--plants-file",
            help="plants file (YAML) of the 'plants' scenario: the plants you list (base parameters, effects and "
            "their values, encoder, name) instead of drawn ones; effect files outside its folder need --trust; "
            "see docs/controllers.md",
        ),
        seed: int = typer.Option(0, "--seed", help="seed of the plant population (and of the measurement noise)"),
        uncertainty: Path = typer.Option(
            None,
            "--uncertainty",
            help="uncertainty set (YAML) of the 'plants' scenario; default controllers/evaluation/plants.yaml",
        ),
        targets: str = typer.Option("", "--targets", help="target speeds (rad/s), comma-separated; default 0.5:8:0.5"),
        duration: float = typer.Option(60.0, "--duration", help="simulated time per run (s), at most 3600"),
        window: float = typer.Option(20.0, "--window", help="steady-state window at the end (s)"),
        workers: int = typer.Option(2, "--workers", help="parallel processes"),
        ray: str | None = typer.Option(
            None,
            "--ray",
            help="run the jobs on Ray: 'auto' (a running cluster), "
            "'local' (start one here with --workers CPUs) or HOST:PORT",
        ),
        params: Path = typer.Option(
            None,
            "--params",
            help="parameter file (JSON/YAML) of the nominal model: "
            "RigParams, or a model file whose effects the plant runs",
        ),
        add_effect: list[str] | None = add_effect_option(),
        effect_param: list[str] | None = effect_param_option(),
        model: Path = typer.Option(
            None,
            "--model",
            help="model file (JSON/YAML: base parameters and effects) the controllers are built on: observer, lqg "
            "and lqg-2enc run all its effects (library names, user and candidate files), the others its base "
            "parameters; default the nominal model (--params) without effects",
        ),
        trust: bool = trust_option(),
        identify: bool = typer.Option(
            False,
            "--identify",
            help="with --scenarios plants: identify each plant first (an excitation run with the plant's lag, delay, "
            "friction and encoders; diagnose; identify) and build every controller on its identified model",
        ),
        excitation: float | None = typer.Option(
            None,
            "--excitation",
            help="length of each plant's excitation run with --identify (s); default 60 torsional, 30 coupled",
        ),
    ) -> None:
        """Evaluate controllers on the scenarios; write a CSV, a markdown table and the SSI figure.
        The plant runs the hidden effects (--add-effect, and a model file's); the controllers do not."""
        from controllers.evaluation import DEFAULT_TARGETS, evaluate, parse_scenarios
        from controllers.evaluation.harness import DURATION_MAX, check_evaluation_options
        from controllers.evaluation.population import load_uncertainty
        from controllers.evaluation.report import write_report
        from drillgym.commands.options import option
        from drillgym.commands.outputs import check_output_dir
        from drillgym.commands.plant import describe_plant, plant_from_cli
        from drillgym.configurations import parse_configuration
        from drillgym.parallel import check_ray_address

        check_output_dir(out)  # refused before the runs, not after them
        cfgs = [c.strip() for c in config.split(",") if c.strip()]
        names = [c.strip() for c in controllers.split(",") if c.strip()]
        if not names:
            raise InputError("--controllers is empty")
        try:
            tg = [float(v) for v in targets.split(",")] if targets.strip() else list(DEFAULT_TARGETS)
        except ValueError as exc:
            raise InputError(f"--targets must be numbers separated by commas, got {targets!r}") from exc
        with option("--config"):
            parsed = [parse_configuration(c) for c in cfgs]
        options = {"controllers": "--controllers", "configs": "--config", "targets": "--targets"}
        options.update({k: "--" + k for k in ("duration", "window", "plants", "seed", "workers")})
        n_drawn = 20 if plants is None else plants
        check_evaluation_options(names, cfgs, tg, duration, window, n_drawn, seed, workers, names=options)
        with option("--scenarios"):
            scen = parse_scenarios(scenarios)
        if ray is not None:
            check_ray_address(ray)
        ident = None
        if identify:
            from controllers.evaluation.identify import ExcitationOptions

            # with --scenarios plants and without --model: the declared dependencies above
            if excitation is not None and not (excitation >= 2.0 and excitation <= DURATION_MAX):
                raise InputError(f"--excitation must be in [2, {DURATION_MAX:g}] s, got {excitation:g}")
            ident = ExcitationOptions(duration=None if excitation is None else float(excitation))
        if uncertainty is not None:  # with --scenarios plants (declared above)
            with option("--uncertainty"):
                uncertainty = load_uncertainty(uncertainty)
        base, comp, values = plant_from_cli(params, add_effect, effect_param, trust, configs=parsed)
        plant_set = None
        if plants_file is not None:  # with --scenarios plants, without --plants/--uncertainty (declared above)
            from controllers.evaluation.plants_file import load_plants

            with option("--plants-file"):
                plant_set = load_plants(plants_file, trust=trust, params=base if params else None)
                for c in parsed:
                    plant_set.refuse_not_acting(c.label)
        ctrl_model = None
        if model is not None:
            from controllers.evaluation.harness import build_controller
            from controllers.model import model_of
            from drillgym.model import Model

            with option("--model"):
                ctrl_model = model_of(Model.load(model, trust=trust))
                for c in names:  # an effect a controller cannot use: refused before any run
                    for cfg in cfgs if not c.startswith("agent:") else ():
                        build_controller(c, cfg, tg[:1], ctrl_model.params, ctrl_model)
            if not params and not any(sc.population for sc in scen):  # said: an identified rig's user expects it run
                typer.echo(
                    "note: --model builds the controllers on the model; the plant is the nominal rig (add --params "
                    f"{model} to run the model as the plant too)",
                    err=True,
                )
        p = base if params else None
        from drillgym.parallel import open_executor

        pool = open_executor(ray, workers) if ray else nullcontext()
        with warnings.catch_warnings(record=True) as caught, pool as ex:
            warnings.simplefilter("always")
            rows = evaluate(
                names,
                cfgs,
                scen,
                tg,
                duration=duration,
                window=window,
                params=p,
                workers=workers,
                effects=comp,
                effect_params=values,
                plants=plants,
                seed=seed,
                uncertainty=uncertainty,
                executor=ex,
                model=ctrl_model,
                identify=ident,
                plants_file=plant_set,
            )
        for w in caught:
            typer.echo(f"warning: {w.message}", err=True)
        files = write_report(rows, out, p, plant=describe_plant(comp, values))
        typer.echo((Path(files["markdown"])).read_text())
        typer.echo("wrote " + ", ".join(str(f) for f in files.values()))
