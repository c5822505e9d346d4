"""``drillgym simulate``: one run of a configuration, written in the interchange format."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from ..configurations import Configuration
from ..errors import InputError
from ..io import U_LIMIT_FILE
from .budget import check_run_fits
from .effect_options import (
    add_effect_option,
    effect_param_option,
    model_option,
    rig_from_cli,
    trust_option,
)
from .options import excludes, option, requires
from .outputs import CREATES_DIRS, check_figure_file, check_output_file, figure_file, output_file


def _load_input(path: Path):
    """(t, u) of an input signal file (csv of docs/data_format.md, or .mat with at least t, u)."""
    from ..io import read_input_signal

    return read_input_signal(path)


def plot_run(traj, path: Path) -> Path:
    """Figure of u, omega_u, omega_l (and r when the disc moves laterally)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lateral = traj.config.lateral_free
    n = 3 if lateral else 2
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.4 * n + 0.6), sharex=True)
    axes[0].plot(traj.t, traj.u, color="k", lw=1)
    axes[0].set_ylabel("u (V)")
    axes[1].plot(traj.t, traj.omega_u, label=r"$\omega_u$", lw=1)
    if traj.config.has_lower:
        axes[1].plot(traj.t, traj.omega_l, label=r"$\omega_l$", lw=1)
        stick = traj.stick_l > 0.5
        if stick.any():
            axes[1].fill_between(
                traj.t,
                0,
                1,
                where=stick,
                transform=axes[1].get_xaxis_transform(),
                color="tab:red",
                alpha=0.12,
                lw=0,
                label="lower disc stuck",
            )
    axes[1].set_ylabel("speed (rad/s)")
    axes[1].legend(loc="upper right", fontsize=8)
    if lateral:
        axes[2].plot(traj.t, 1e3 * traj.r, lw=1, color="tab:green")
        axes[2].set_ylabel("r (mm)")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(f"drillgym simulate: {traj.config.label}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def check_input_span(t, path: Path, duration: float | None) -> float:
    """The run's duration (s) for an input file sampled at ``t`` (s): ``duration`` if the file covers
    [0, duration), else a one-line error; None -> the file's own length (its last sample held one interval)."""
    import numpy as np

    if t[0] > 1e-9:
        raise InputError(f"--input {path}: starts at t = {t[0]:g} s; the run starts at 0 s (shift the file's times)")
    span = float(t[-1] + (t[-1] - t[-2] if len(t) > 1 else 0.0))
    if duration is None:
        return span
    if np.isfinite(duration) and duration > span * (1 + 1e-9) + 1e-9:
        raise InputError(
            f"--input {path} covers {span:g} s, shorter than --duration {duration:g} s: shorten "
            f"--duration (or leave it out to run the file's length) or extend the file"
        )
    return duration


def check_step_grid(duration: float, dt: float, record_every: int, duration_given: bool = True) -> None:
    """Refuse a step or a recording interval that would cut the run short or leave its end unrecorded.

    Parameters
    ----------
    duration : float
        ``--duration`` (s).
    dt : float
        ``--dt`` (s).
    record_every : int
        ``--record-every``.
    duration_given : bool, optional
        Whether the user gave ``--duration``; a duration taken from an ``--input`` file's length ends on
        the nearest step instead of being refused.

    Raises
    ------
    InputError
        ``dt`` does not divide ``duration``, or ``record_every`` does not divide the number of steps.
    """
    if not (math.isfinite(duration) and math.isfinite(dt) and duration > 0 and dt > 0):
        return  # the simulator names a bad duration or step
    steps = duration / dt
    if not math.isfinite(steps):
        return  # beyond any memory: the budget names it (check_run_fits)
    n_steps = round(steps)
    if n_steps < 1 or (duration_given and abs(steps - n_steps) > 1e-6 * max(1.0, steps)):
        raise InputError(
            f"--dt {dt:g} s does not divide --duration {duration:g} s ({steps:.6g} steps): the run would end "
            f"at {n_steps * dt:g} s; choose a step that divides the duration"
        )
    if record_every < 1:
        raise InputError(f"--record-every must be >= 1, got {record_every}")
    if n_steps % record_every:
        raise InputError(
            f"--record-every {record_every} does not divide the run's {n_steps} steps: its end "
            f"({duration:g} s) would not be recorded; choose a divisor of {n_steps}"
        )


#: largest initial winding |--alpha0| (rad) a run may start from: ten turns of the string
ALPHA0_LIMIT = 20 * math.pi

#: the integration methods of ``--method``
METHODS = ("rk4", "dp5")


def _finite(option: str, value: float, unit: str) -> None:
    if not math.isfinite(value):
        raise InputError(f"{option} must be a finite number of {unit}, got {value:g}")


def check_run_options(
    u: float | None, duration: float | None, dt: float, method: str, alpha0: float | None, record_every: int
) -> None:
    """Refuse, in the options' terms and before anything is read or run, values no run can use.

    Parameters
    ----------
    u : float or None
        ``--u`` (V): finite (its range is checked against the file format's limit by the caller).
    duration : float or None
        ``--duration`` (s): finite and positive when given.
    dt : float
        ``--dt`` (s): in (0, 0.1].
    method : str
        ``--method``: one of :data:`METHODS`.
    alpha0 : float or None
        ``--alpha0`` (rad): finite, at most :data:`ALPHA0_LIMIT` in magnitude.
    record_every : int
        ``--record-every``: at least 1.

    Raises
    ------
    InputError
        Naming the option, the value and what would be valid.
    """
    if u is not None:
        _finite("--u", u, "volts")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise InputError(f"--duration must be a positive number of seconds, got {duration:g}")
    if not (math.isfinite(dt) and 0 < dt <= 0.1):
        raise InputError(f"--dt must be a step in (0, 0.1] s, got {dt:g}")
    if method not in METHODS:
        raise InputError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    if alpha0 is not None:
        _finite("--alpha0", alpha0, "radians")
        if abs(alpha0) > ALPHA0_LIMIT:
            raise InputError(
                f"--alpha0 {alpha0:g} rad is beyond the +-{ALPHA0_LIMIT:.4g} rad (ten turns) a string can be "
                f"wound; choose |alpha0| <= {ALPHA0_LIMIT:.4g}"
            )
    if record_every < 1:
        raise InputError(f"--record-every must be >= 1, got {record_every}")


def _summary(traj) -> str:
    """The one-line result: final speed and stuck time of the disc(s) the configuration has."""
    if traj.config is Configuration.UPPER:
        return (
            f"final omega_u = {traj.omega_u[-1]:.4f} rad/s, upper disc stuck "
            f"{100 * traj.stick_u.mean():.1f} % of the time"
        )
    return (
        f"final omega_l = {traj.omega_l[-1]:.4f} rad/s, lower disc stuck {100 * traj.stick_l.mean():.1f} % of the time"
    )


def register(app: typer.Typer) -> None:
    @app.command("simulate")
    @excludes("--model", "--params", why="the model file holds its base parameters")
    @excludes("--model", "--add-effect", why="the model file holds its effects")
    @excludes("--model", "--effect-param", why="the model file holds its effects' values")
    @requires("--trust", "--model", why="it trusts the effect files a model file names")
    def simulate_cmd(
        config: str = typer.Option("torsional", help="upper, torsional, lateral, coupled or free_vibration"),
        u: float | None = typer.Option(
            None,
            help=f"constant motor voltage (V), |u| <= {U_LIMIT_FILE:g} V (what the "
            "time-series format accepts; the rig's amplifier gives +-5 V); "
            "not for free_vibration",
        ),
        input_file: Path | None = typer.Option(
            None, "--input", help="input signal file (csv or .mat with t, u, from t = 0) instead of --u"
        ),
        duration: float | None = typer.Option(
            None, help="simulated time (s); default 30, with --input the file's length (a longer one is refused)"
        ),
        dt: float = typer.Option(1e-3, help="integration step (s), at most 0.1; must divide --duration"),
        method: str = typer.Option("rk4", help="rk4 or dp5"),
        params: Path | None = typer.Option(
            None, help="parameter file (JSON/YAML, may be partial: the names it gives override the identified set)"
        ),
        alpha0: float | None = typer.Option(
            None,
            help=f"initial winding theta_l - theta_u (rad), |alpha0| <= {ALPHA0_LIMIT:.4g} (ten turns); default 0; "
            "free_vibration needs it: the angle the lower disc is "
            "twisted by and released from",
        ),
        record_every: int = typer.Option(1, help="keep every k-th step in the output (a divisor of the steps)"),
        out: Path = typer.Option(..., help=f"output csv (docs/data_format.md); {CREATES_DIRS}"),
        plot: Path | None = typer.Option(None, help=f"also write a figure (png); {CREATES_DIRS}"),
        add_effect: list[str] = add_effect_option(),
        effect_param: list[str] = effect_param_option(),
        model_file: Path | None = model_option(),
        trust: bool = trust_option(),
    ) -> None:
        """Simulate from rest and write the run as csv (docs/data_format.md) and a figure.

        free_vibration (report 3.3) holds the upper disc and releases the lower disc from a
        winding: give --alpha0, no voltage (e.g. --config free_vibration --alpha0 1.0 --duration 20).
        """
        from ..configurations import parse_configuration
        from ..simulator import simulate

        with option("--config"):
            cfg = parse_configuration(config)
        check_run_options(u, duration, dt, method, alpha0, record_every)
        if cfg is Configuration.FREE_VIBRATION:
            if u is not None or input_file is not None:
                raise InputError(
                    "free_vibration holds the upper disc (the motor voltage has no effect): leave out "
                    "--u/--input and give --alpha0 RAD, the release angle"
                )
            if alpha0 is None:
                raise InputError(
                    "free_vibration releases the lower disc from a winding: give --alpha0 RAD (e.g. --alpha0 1.0)"
                )
        elif (u is None) == (input_file is None):
            raise InputError("give exactly one of --u VOLTS or --input FILE")
        if u is not None and not abs(u) <= U_LIMIT_FILE:  # finite: checked above
            raise InputError(
                f"--u {u:g} V is beyond the +-{U_LIMIT_FILE:g} V a recording may hold (the rig's "
                f"amplifier gives +-5 V); choose |u| <= {U_LIMIT_FILE:g} V"
            )
        duration_given = duration is not None
        rig, comp, values = rig_from_cli(model_file, trust, cfg, params, add_effect, effect_param)
        if input_file is not None:
            with option("--input"):
                signal = _load_input(input_file)  # its values are checked by the reader (|u| <= 50 V)
            duration = check_input_span(signal[0], input_file, duration)
        else:
            signal = float(u) if u is not None else 0.0
            duration = 30.0 if duration is None else duration
        if input_file is not None and out.resolve() == input_file.resolve():
            raise InputError(f"--out {out} is the --input file: the run would replace its input; choose another name")
        check_step_grid(duration, dt, record_every, duration_given=duration_given)
        check_run_fits(duration, dt, record_every, out)
        check_output_file(out, "--out", suffixes=(".csv",))
        if plot:
            check_figure_file(plot)
        traj = simulate(
            cfg,
            signal,
            duration,
            dt=dt,
            params=rig,
            alpha0=alpha0 or 0.0,
            method=method,
            record_every=record_every,
            effects=comp,
            effect_params=values,
        )
        how = (
            f"--u {u}" if u is not None else f"--input {input_file}" if input_file is not None else f"--alpha0 {alpha0}"
        )
        if model_file is not None:
            how += f" --model {model_file}"
        else:
            how += "".join(f" --add-effect {s}" for s in comp.specs()) + "".join(
                f" --effect-param {k}={v:g}" for k, v in values.items()
            )
        out = output_file(out, "--out", suffixes=(".csv",))  # its directories created once the run succeeded
        plot = figure_file(plot) if plot else None
        traj.to_csv(out, description=f"drillgym simulate --config {cfg.label} {how}")
        typer.echo(f"wrote {out} ({len(traj.t)} samples); {_summary(traj)}")
        if plot:
            plot_run(traj, plot)
            typer.echo(f"wrote {plot}")
