"""``drillgym simulate``: one run of a configuration, written in the interchange format."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..configurations import Configuration
from .effect_options import add_effect_option, effect_param_option, effects_from_cli


def _load_input(path: Path):
    """(t, u) of an input signal file (DATA_FORMAT csv or .mat with at least t, u)."""
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
            axes[1].fill_between(traj.t, 0, 1, where=stick, transform=axes[1].get_xaxis_transform(),
                                 color="tab:red", alpha=0.12, lw=0, label="lower disc stuck")
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


def register(app: typer.Typer) -> None:
    @app.command("simulate")
    def simulate_cmd(
        config: str = typer.Option("torsional", help="upper, torsional, lateral, coupled or free_vibration"),
        u: Optional[float] = typer.Option(None, help="constant motor voltage (V); any value, no amplifier limit"),
        input_file: Optional[Path] = typer.Option(None, "--input", help="input signal file (csv with t, u) instead of --u"),
        duration: float = typer.Option(30.0, help="simulated time (s)"),
        dt: float = typer.Option(1e-3, help="integration step (s)"),
        method: str = typer.Option("rk4", help="rk4 or dp5"),
        params: Optional[Path] = typer.Option(None, help="parameter file (JSON/YAML); default: identified set"),
        alpha0: float = typer.Option(0.0, help="initial winding theta_l - theta_u (rad)"),
        record_every: int = typer.Option(1, help="keep every k-th step in the output"),
        out: Path = typer.Option(..., help="output csv (DATA_FORMAT)"),
        plot: Optional[Path] = typer.Option(None, help="also write a figure (png)"),
        add_effect: List[str] = add_effect_option(),
        effect_param: List[str] = effect_param_option(),
    ) -> None:
        """Simulate from rest and write the run as DATA_FORMAT csv (and a figure)."""
        from ..params import RigParams
        from ..simulator import simulate

        if (u is None) == (input_file is None):
            raise ValueError("give exactly one of --u VOLTS or --input FILE")
        comp, values = effects_from_cli(add_effect, effect_param)
        rig = RigParams.from_file(params) if params else RigParams()
        signal = float(u) if u is not None else _load_input(input_file)
        traj = simulate(config, signal, duration, dt=dt, params=rig, alpha0=alpha0, method=method,
                        record_every=record_every, effects=comp, effect_params=values)
        added = "".join(f" --add-effect {s}" for s in comp.specs()) + "".join(
            f" --effect-param {k}={v:g}" for k, v in values.items())
        traj.to_csv(out, description=f"drillgym simulate --config {config} "
                                      + (f"--u {u}" if u is not None else f"--input {input_file}") + added)
        stuck = traj.stick_l.mean() if traj.config is not Configuration.UPPER else traj.stick_u.mean()
        typer.echo(f"wrote {out} ({len(traj.t)} samples); final omega_l = {traj.omega_l[-1]:.4f} rad/s, "
                   f"lower disc stuck {100 * stuck:.1f} % of the time")
        if plot:
            plot_run(traj, plot)
            typer.echo(f"wrote {plot}")
