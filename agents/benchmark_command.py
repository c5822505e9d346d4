"""``drillgym benchmark TASK --policy SPEC``: a policy's score on a named task (:mod:`.benchmark`).

Registered by :func:`agents.commands.register` (entry-point group ``drillgym.commands``).
"""

from __future__ import annotations

from pathlib import Path

import typer

from drillgym.errors import InputError

__all__ = ["register_benchmark", "parse_seeds"]


def parse_seeds(text: str) -> list[int]:
    """``"1,2,5"`` or ``"1-5"`` (or both, comma-separated) -> seeds, each >= 0, no repeats.

    Raises
    ------
    InputError
        Anything else, naming ``--seeds``.
    """
    out: list[int] = []
    try:
        for part in (p.strip() for p in text.split(",") if p.strip()):
            a, _, b = part.partition("-")
            lo, hi = int(a), int(b) if b else int(a)
            if lo < 0 or hi < lo:
                raise ValueError
            out += range(lo, hi + 1)
    except ValueError:
        raise InputError(f"--seeds must be seeds >= 0 as 1,2,3 or 1-5, got {text!r}") from None
    if not out or len(set(out)) != len(out):
        raise InputError(f"--seeds must name each seed once, got {text!r}")
    return out


def register_benchmark(app: typer.Typer) -> None:
    """Add ``benchmark`` to the ``drillgym`` application.

    Parameters
    ----------
    app : typer.Typer
        The ``drillgym`` command-line application.
    """

    from drillgym.commands.effect_options import model_option, trust_option
    from drillgym.commands.options import excludes, requires

    @app.command("benchmark")
    @excludes("--model", "--plants", why="the run has the model's plant only, not the task's held-out plants")
    @excludes("--model", "--identified", why="the run has the model's plant only, not the task's identified plants")
    @requires("--trust", "--model", why="it trusts the effect files a model file names")
    def benchmark_cmd(
        task: str = typer.Argument(..., help="task id, e.g. drillgym/Population-Motor-v0 (see docs/benchmark.md)"),
        policy: list[str] = typer.Option(
            ...,
            "--policy",
            help="a classical controller (NAME or NAME@MS, as `evaluate --controllers`) or agent:PATH (a "
            "policy.npz, a run directory, or a directory of seed_<s>/ runs); repeat agent:PATH for the seeds of "
            "one policy",
        ),
        seeds: str = typer.Option("", "--seeds", help="with agent:DIR of seed_<s>/ runs: the seeds, 1,2,3 or 1-5"),
        plants: int | None = typer.Option(
            None, "--plants", help="only the first N held-out plants (a REDUCED protocol, marked as such)"
        ),
        duration: float | None = typer.Option(None, "--duration", help="run length (s); REDUCED if not the task's"),
        window: float | None = typer.Option(None, "--window", help="steady window (s); REDUCED if not the task's"),
        targets: str = typer.Option("", "--targets", help="target speeds (rad/s), comma-separated; REDUCED if given"),
        workers: int = typer.Option(1, "--workers", help="processes of the evaluation harness"),
        json_out: Path | None = typer.Option(
            None, "--json", help="also write the result as JSON to this file; missing directories are created"
        ),
        progress: bool = typer.Option(False, "--progress/--no-progress", help="the harness's progress bar"),
        model_file: Path | None = model_option(
            "model file (JSON/YAML, drillgym.Model, e.g. what `drillgym identify` wrote): score the policy on that "
            "model's plant alone (the task's sensors, targets and run length; not the task's score)"
        ),
        trust: bool = trust_option(),
        identified: Path | None = typer.Option(
            None,
            "--identified",
            help="on an -Identified-v0 task: folder of the held-out plants' identified models; the plants it "
            "lacks are identified and written there, so the next policy is scored without identifying again",
        ),
    ) -> None:
        """Score a policy on a named task: lowest held target at the median and 90th percentile of the
        held-out plants, SSI, whirl (a coupled task's target is held only below the whirl threshold), energy;
        over several policy seeds their IQM with a stratified-bootstrap 95 % interval (rliable)."""
        from agents.benchmark import BenchmarkOptions, resolve_policies, run_benchmark
        from controllers.evaluation.harness import check_evaluation_options
        from drillgym.commands.options import option
        from drillgym.commands.outputs import check_output_file, output_file
        from drillgym.envs.tasks import get_task
        from drillgym.io.jsonfile import write_json

        with option("TASK"):
            t = get_task(task)
        m = None
        if model_file is not None:
            from drillgym.commands.effect_options import model_from_cli
            from drillgym.configurations import parse_configuration

            m = model_from_cli(model_file, trust, parse_configuration(t.config))
        if json_out is not None:
            check_output_file(json_out, "--json", suffixes=(".json",))
        specs = resolve_policies(policy, parse_seeds(seeds) if seeds.strip() else None)
        try:
            tg = tuple(float(v) for v in targets.split(",")) if targets.strip() else None
        except ValueError:
            raise InputError(f"--targets must be numbers separated by commas, got {targets!r}") from None
        opts = BenchmarkOptions(plants, duration, window, tg, workers, progress, identified)
        st = opts.settings(t)
        names = {"controllers": "--policy", "configs": "TASK", "targets": "--targets", "duration": "--duration"}
        names.update(window="--window", plants="--plants", workers="--workers")
        check_evaluation_options(
            specs, [t.config], list(st["targets"]), st["duration"], st["window"], st["plants"], 0, workers, names
        )
        if t.identified and identified is None and m is None:
            typer.echo(
                f"note: identifying the {st['plants']} held-out plant(s) first and keeping nothing; --identified DIR "
                "keeps their models for the next policy",
                err=True,
            )
        res = run_benchmark(t.id, specs, opts, model=m)
        for line in res.lines():
            typer.echo(line)
        if json_out is not None:
            path = write_json(output_file(json_out, "--json", suffixes=(".json",)), res.to_json())
            typer.echo(f"wrote {path}")
