"""``drillgym bifurcation``: open-loop bifurcation diagrams (report chapter 4) with figures and JSON."""

from __future__ import annotations

import os
from pathlib import Path

import typer

from ..errors import InputError
from .effect_options import (
    add_effect_option,
    effect_param_option,
    model_option,
    rig_from_cli,
    trust_option,
)
from .options import excludes, option, requires
from .outputs import check_output_dir, output_dir


def register(app: typer.Typer) -> None:
    @app.command("bifurcation")
    @requires("--no-report", "--measured", why="it leaves out the measured points")
    @requires("--sweep-duration", "--sweep-step", when=lambda v: v > 0, what="a --sweep-step above 0 (sweeps)")
    @excludes("--model", "--params", why="the model file holds its base parameters")
    @excludes("--model", "--add-effect", why="the model file holds its effects")
    @excludes("--model", "--effect-param", why="the model file holds its effects' values")
    @requires("--trust", "--model", why="it trusts the effect files a model file names")
    def bifurcation(
        config: str = typer.Option("torsional", "--config", help="torsional, lateral or coupled"),
        out: Path = typer.Option(
            ..., "--out", help="output directory (figures, branches.json); missing directories are created"
        ),
        umin: float = typer.Option(0.0, "--umin", help="lowest voltage (V)"),
        umax: float | None = typer.Option(None, "--umax", help="highest voltage (V); default 5 (lateral: 50)"),
        measured: list[Path] | None = typer.Option(None, "--measured", help="constant-voltage measurement files"),
        params: Path | None = typer.Option(None, "--params", help="parameter file (JSON/YAML)"),
        sweep_step: float = typer.Option(
            0.05, "--sweep-step", help="voltage step of the brute-force sweeps (V), at most 2001 voltages; 0: none"
        ),
        sweep_duration: float = typer.Option(
            120.0, "--sweep-duration", help="simulated seconds per sweep voltage, 20 (its steady-state window) to 3600"
        ),
        no_report: bool = typer.Option(False, "--no-report", help="leave out the report's measured points"),
        ds_max: float = typer.Option(
            0.2,
            "--ds-max",
            help="largest continuation step (arclength); 1.0 follows the whole lateral whirl branch (slower)",
        ),
        ray: str | None = typer.Option(
            None,
            "--ray",
            help="run the sweeps on Ray: 'auto' (a running cluster), 'local' (start one here) or HOST:PORT",
        ),
        add_effect: list[str] = add_effect_option(),
        effect_param: list[str] = effect_param_option(),
        model_file: Path | None = model_option(),
        trust: bool = trust_option(),
    ) -> None:
        """Equilibria, Hopf points, periodic branches (shooting + continuation), folds, sweeps; figures + JSON."""
        from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        from ..bifurcation import compute_diagram, measured_diagram
        from ..bifurcation.diagram import check_diagram_options
        from ..bifurcation.plots import save_figures
        from ..configurations import parse_configuration
        from ..parallel import check_ray_address

        check_output_dir(out)  # refused now, not after the minutes of the diagram
        with option("--config"):
            cfg = parse_configuration(config)
        if cfg.label not in ("torsional", "lateral", "coupled"):
            raise InputError(f"--config must be torsional, lateral or coupled, got {config!r}")
        hi = umax if umax is not None else (50.0 if cfg.label == "lateral" else 5.0)
        lateral = cfg.label == "lateral"
        names = {k: "--" + k.replace("_", "-") for k in ("umin", "umax", "sweep_step", "sweep_duration", "ds_max")}
        check_diagram_options(
            umin, hi, sweep_step, sweep_duration, ds_max, sweep_umax=min(hi, 5.0) if lateral else None, names=names
        )
        if ray is not None:
            check_ray_address(ray)
        from ..equilibria import RigModel

        rig, comp, values = rig_from_cli(model_file, trust, cfg, params, add_effect, effect_param)
        p = RigModel(rig, comp, values)
        with option("--measured"):
            meas = measured_diagram(measured, cfg.label) if measured else []
        # one bar per kind of work: continuation points (open-ended: a branch stops at a fold, a Hopf
        # point or the window) and sweep voltages (total known once the sweeps start)
        from contextlib import nullcontext

        from ..parallel import open_executor

        executor = open_executor(ray, os.cpu_count() or 1) if ray is not None else nullcontext()  # before any work
        with (
            executor as ex,
            Progress(
                SpinnerColumn(),
                TextColumn("{task.description:<30}"),
                BarColumn(),
                TextColumn("{task.completed:>5.0f}/{task.fields[of]}"),
                TimeElapsedColumn(),
            ) as bar,
        ):
            stage = bar.add_task(f"{cfg.label}: start", total=None, of="-")
            cycles = bar.add_task("cycles (continuation points)", total=None, of="?", visible=False)
            sweeps = bar.add_task("sweeps (voltages)", total=None, of="?", visible=False)

            def completed(task_id) -> float:
                return next(t.completed for t in bar.tasks if t.id == task_id)

            def on_progress(message: str) -> None:
                if message.startswith("cycle"):
                    bar.update(cycles, description=f"cycles: {message[6:]}")
                else:
                    bar.update(stage, description=f"{cfg.label}: {message}")

            def on_step(kind: str, k: int) -> None:
                if kind == "cycle":
                    bar.update(cycles, advance=k, visible=True)
                elif kind == "sweep_total":
                    bar.update(sweeps, total=k, of=str(k), visible=True)
                    bar.update(cycles, total=completed(cycles), of=f"{completed(cycles):.0f}")
                elif kind == "sweep":
                    bar.update(sweeps, advance=k)

            diag = compute_diagram(
                cfg.label,
                p,
                umin=umin,
                umax=hi,
                sweep_step=sweep_step or None,
                sweep_duration=sweep_duration,
                staircase=not lateral,
                sweep_umax=min(hi, 5.0) if lateral else None,  # the report's lab range
                measured=meas,
                ds_max=ds_max,
                progress=on_progress,
                step=on_step,
                executor=ex,
            )
            n_cycles = completed(cycles)
            bar.update(cycles, total=n_cycles, of=f"{n_cycles:.0f}")
            bar.update(stage, total=1, completed=1, description=f"{cfg.label}: done")
        out = output_dir(out)
        paths = save_figures(diag, out, report=not no_report)
        diag.save_json(out / "branches.json")
        typer.echo(f"Hopf points (V): {[round(h.u, 4) for h in diag.hopf]}")
        typer.echo(f"folds (V): {[round(f.u, 4) for f in diag.folds]}")
        for pth in paths + [out / "branches.json"]:
            typer.echo(f"wrote {pth}")
