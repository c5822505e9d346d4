"""``drillgym evaluate``: controllers (and agents) on the evaluation harness.

The controllers live in the top-level ``controllers`` package, imported lazily
here (the core does not depend on it).
"""

from __future__ import annotations

from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command("evaluate")
    def evaluate_cmd(
        config: str = typer.Option("torsional,coupled", "--config", help="configuration(s), comma-separated"),
        controllers: str = typer.Option("baseline,pi,softtorque,observer", "--controllers",
                                        help="comma-separated: baseline, pi, softtorque, observer, lqg, agent:PATH; "
                                             "NAME@MS sets the control period, e.g. observer@10"),
        out: Path = typer.Option(..., "--out", help="output directory (results.csv, summary.md, figure); missing directories are created"),
        scenarios: str = typer.Option("rest", "--scenarios",
                                      help="comma-separated: rest, cycle, friction-20, friction+20, noisy"),
        targets: str = typer.Option("", "--targets", help="target speeds (rad/s), comma-separated; default 0.5:8:0.5"),
        duration: float = typer.Option(60.0, "--duration", help="simulated time per run (s)"),
        window: float = typer.Option(20.0, "--window", help="steady-state window at the end (s)"),
        workers: int = typer.Option(2, "--workers", help="parallel processes"),
        params: Path = typer.Option(None, "--params", help="parameter file (JSON/YAML) of the model"),
    ) -> None:
        """Evaluate controllers on the scenarios; write a CSV, a markdown table and the SSI figure."""
        from controllers.evaluation import DEFAULT_TARGETS, evaluate, parse_scenarios
        from controllers.evaluation.report import write_report
        from drillgym import RigParams

        cfgs = [c.strip() for c in config.split(",") if c.strip()]
        names = [c.strip() for c in controllers.split(",") if c.strip()]
        if not names:
            raise ValueError("--controllers is empty")
        try:
            tg = [float(v) for v in targets.split(",")] if targets.strip() else list(DEFAULT_TARGETS)
        except ValueError as exc:
            raise ValueError(f"--targets must be numbers separated by commas, got {targets!r}") from exc
        p = RigParams.from_file(params) if params else None
        rows = evaluate(names, cfgs, parse_scenarios(scenarios), tg, duration=duration, window=window, params=p,
                        workers=workers)
        files = write_report(rows, out, p)
        typer.echo((Path(files["markdown"])).read_text())
        typer.echo("wrote " + ", ".join(str(f) for f in files.values()))
