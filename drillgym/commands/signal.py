"""CLI: ``signal``, an excitation signal (the report's estimation and validation inputs) as an input file."""

from __future__ import annotations

from pathlib import Path

import typer

from ..errors import InputError
from .outputs import CREATES_DIRS, check_output_file, output_file

#: the options of ``drillgym signal`` by the argument of :func:`drillgym.signals.check_signal` they set
SIGNAL_OPTIONS = {"duration": "--duration", "rate_hz": "--rate", "amplitude": "--amplitude", "offset": "--offset"}


def _check_signal(duration: float, rate: float, amplitude: float, offset: float, seed: int) -> None:
    """Refuse, naming the option, a signal no file can hold: checked before anything is generated."""
    from ..signals import check_signal

    check_signal(duration, rate, amplitude, offset, seed, names={**SIGNAL_OPTIONS, "seed": "--seed"})


def signal_cmd(
    out: Path = typer.Argument(..., help=f"output CSV (columns t, u); {CREATES_DIRS}"),
    kind: str = typer.Option("quasi_random", "--kind", help="quasi_random (estimation) or sum_of_sines (validation)"),
    duration: float = typer.Option(60.0, help="duration (s)"),
    rate: float = typer.Option(1000.0, help="sample rate (Hz)"),
    amplitude: float = typer.Option(5.0, help="largest |u| (V); the signal spans offset ± (amplitude - |offset|)"),
    offset: float = typer.Option(0.0, help="mean voltage (V)"),
    seed: int = typer.Option(0, help="random seed"),
) -> None:
    """Write an excitation signal (the report's estimation/validation inputs) as an input file."""
    from ..signals import quasi_random, sum_of_sines, write_input_file

    gens = {"quasi_random": quasi_random, "sum_of_sines": sum_of_sines}
    check_output_file(out, "OUT", suffixes=(".csv",))
    if kind not in gens:
        raise InputError(f"--kind must be one of {', '.join(gens)}, got {kind!r}")
    _check_signal(duration, rate, amplitude, offset, seed)
    t, u = gens[kind](duration, rate_hz=rate, seed=seed, amplitude=amplitude, offset=offset)
    write_input_file(output_file(out, "OUT", suffixes=(".csv",)), t, u, description=f"{kind}, seed {seed}")
    typer.echo(f"wrote {out}: {kind}, {duration:g} s at {rate:g} Hz, u in [{u.min():.2f}, {u.max():.2f}] V")


def register(app: typer.Typer) -> None:
    """Add the command ``signal``.

    Parameters
    ----------
    app : typer.Typer
        The command-line application.
    """
    app.command("signal")(signal_cmd)
