"""``drillgym rig``: the hardware twin.

    drillgym rig emulate [--port PATH] [--params FILE] [--add-effect NAME|file.py:NAME] [--effect-param N=V] ...
        emulate the rig's microcontroller on a pseudo-terminal (prints the device path); the
        plant runs the hidden effects (and those of a model file given to --params)
    drillgym rig run --port PATH (--controller NAME | --policy FILE) --duration S --record FILE
        run a controller or a policy on the rig through drillgym/Hardware-v0, recording it
"""

from __future__ import annotations

import signal
from pathlib import Path
from typing import List, Optional

import typer

from .effect_options import add_effect_option, effect_param_option
from .plant import describe_plant, plant_from_cli

rig_app = typer.Typer(no_args_is_help=True, help="hardware twin: run on the rig, or emulate it on a pseudo-terminal")


def _interrupt(*_) -> None:
    raise KeyboardInterrupt


@rig_app.command("emulate")
def emulate_cmd(
    port: Optional[Path] = typer.Option(None, help="also create a symlink to the pseudo-terminal here"),
    config: str = typer.Option("torsional", help="rig configuration: torsional, lateral or coupled"),
    params: Optional[Path] = typer.Option(None, help="parameter file (JSON/YAML) of the emulated rig: RigParams or "
                                                     "a model file with effects (identify --out)"),
    add_effect: Optional[List[str]] = add_effect_option(),
    effect_param: Optional[List[str]] = effect_param_option(),
    counts_per_rev: int = typer.Option(8000, help="encoder counts per revolution"),
    lvdt_noise: float = typer.Option(3e-6, help="LVDT noise standard deviation (m)"),
    latency_ms: float = typer.Option(0.0, help="serial latency of every reply (ms)"),
    jitter_ms: float = typer.Option(0.0, help="extra uniform random latency up to this (ms)"),
    period_ms: float = typer.Option(10.0, help="default control period (ms); the host may change it"),
    watchdog_ms: float = typer.Option(100.0, help="motor to 0 V after this long without a command (ms)"),
    dt: float = typer.Option(1e-3, help="integration step of the emulated plant (s)"),
    alpha0: float = typer.Option(0.0, help="initial winding of the string (rad)"),
    seed: int = typer.Option(0, help="seed of the LVDT noise and latency jitter"),
) -> None:
    """Emulate the rig's microcontroller on a pseudo-terminal until Ctrl-C.  The plant runs the hidden
    effects (--add-effect, and those of a model file in --params); the host does not know them."""
    from hw.emulator import RigEmulator
    from hw.firmware import FirmwareConfig

    base, comp, values = plant_from_cli(params, add_effect, effect_param)
    fw = FirmwareConfig(counts_per_rev=counts_per_rev, control_period_s=period_ms * 1e-3,
                        watchdog_s=watchdog_ms * 1e-3)
    emu = RigEmulator(config, base, fw, effects=comp, effect_params=values, dt=dt, alpha0=alpha0,
                      lvdt_noise_std=lvdt_noise, seed=seed, latency_s=latency_ms * 1e-3, jitter_s=jitter_ms * 1e-3,
                      link_path=port)
    emu.start()
    signal.signal(signal.SIGTERM, _interrupt)
    typer.echo(f"rig emulator ({config}) on {emu.port}" + (f" (link {port})" if port else "")
               + f"; {describe_plant(comp, values)}", err=False)
    typer.echo("Ctrl-C to stop", err=True)
    try:
        emu.serve_forever()
    except KeyboardInterrupt:
        emu.stop()


@rig_app.command("run")
def run_cmd(
    port: str = typer.Option(..., help="serial device or pyserial URL of the rig (or of `drillgym rig emulate`)"),
    controller: Optional[str] = typer.Option(None, help="controller: const:<volts> or a name from controllers/"),
    policy: Optional[Path] = typer.Option(None, help="policy file (.npz linear W, b; others via agents/)"),
    duration: float = typer.Option(10.0, help="episode length (s)"),
    record: Path = typer.Option(Path("rig_run.csv"), help="recording file (DATA_FORMAT csv)"),
    config: str = typer.Option("torsional", help="how the rig is set up: torsional, lateral or coupled"),
    observation: str = typer.Option("sensors", help="policy observation: full, sensors or motor"),
    omega_ref: Optional[float] = typer.Option(None, help="target lower-disc speed (rad/s); default drawn per seed"),
    control_ms: float = typer.Option(10.0, help="control period (ms)"),
    seed: int = typer.Option(0, help="episode seed"),
    reply_timeout_ms: float = typer.Option(50.0, help="longest wait for the firmware's reply (ms), below its "
                                                       "100 ms watchdog; raise it for an emulator on a busy machine"),
) -> None:
    """Run one episode of a controller or a policy on the rig, recorded to --record."""
    import gymnasium as gym
    import numpy as np

    import hw
    from hw.runner import load_policy, make_controller, run_episode

    if (controller is None) == (policy is None):
        raise ValueError("give exactly one of --controller or --policy")
    if not duration > 0:
        raise ValueError(f"--duration must be > 0 s, got {duration}")
    hw.register()
    opts = {"observation": observation, "episode_duration": duration, "control_dt": control_ms * 1e-3}
    if omega_ref is not None:
        opts["omega_ref"] = omega_ref
    env = gym.make(hw.ENV_ID, port=port, configuration=config, record=record, reply_timeout=reply_timeout_ms * 1e-3,
                   **opts)
    try:
        ctrl = make_controller(controller, config, omega_ref, control_ms * 1e-3) if controller else None
        pol = load_policy(policy) if policy is not None else None
        res = run_episode(env, controller=ctrl, policy=pol, seed=seed)
    finally:
        env.close()
    ms = 1e3
    typer.echo(f"{res.steps} steps, return {res.total_reward:.2f}, "
               f"{'terminated' if res.terminated else 'truncated' if res.truncated else 'stopped'}"
               + (f" (safety stop: {res.safety_stop})" if res.safety_stop else ""))
    if res.steps:
        typer.echo(f"round trip median {ms * np.median(res.round_trips):.2f} ms, max {ms * res.round_trips.max():.2f} ms; "
                   f"tick error p99 {ms * np.percentile(res.tick_errors, 99):.2f} ms")
    typer.echo(f"recording: {res.recording}")


def register(app: typer.Typer) -> None:
    app.add_typer(rig_app, name="rig")
