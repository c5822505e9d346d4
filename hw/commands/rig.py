"""``drillgym rig``: the hardware twin.

    drillgym rig emulate [--port PATH] [--params FILE] [--add-effect NAME|file.py:NAME] [--effect-param N=V] ...
    drillgym rig emulate [--port PATH] --model MODEL.json [--trust] ...
        emulate the rig's microcontroller on a pseudo-terminal (prints the device path); the
        plant runs the hidden effects (and those of a model file given to --params), or the model of --model
    drillgym rig run --port PATH (--controller NAME | --policy FILE) --duration S --record FILE [--dry-run]
        run a controller or a policy on the rig through drillgym/Hardware-v0, recording it
    drillgym rig tune --port PATH --model-out MODEL.json [--duration S] [--control-ms MS]
        identify the rig (excitation run, diagnose + identify) into the model file its controllers read
        (:mod:`hw.commands.tune`)
    drillgym rig estop --port PATH
        emergency stop: motor to 0 V, latched until the next run's handshake

``rig run`` exits 0 when the episode ran its course, 3 on a safety stop (one line with the
reason; motor at 0 V, recording kept), 130 when interrupted (Ctrl-C, SIGTERM), 2 on a bad
option (nothing moved); see :mod:`hw.commands.rig_ops`.
"""

from __future__ import annotations

import signal
from contextlib import contextmanager
from pathlib import Path

import typer

from drillgym.commands.effect_options import (
    add_effect_option,
    effect_param_option,
    model_from_cli,
    model_option,
    trust_option,
)
from drillgym.commands.options import excludes, requires
from drillgym.commands.outputs import CREATES_DIRS
from drillgym.commands.plant import describe_plant, plant_from_cli
from drillgym.errors import InputError, MissingFileError, SafetyError

from .rig_ops import INTERRUPT_EXIT, STOP_EXIT, ClampNotice, stop_reason

rig_app = typer.Typer(no_args_is_help=True, help="hardware twin: run on the rig, or emulate it on a pseudo-terminal")


def _interrupt(*_) -> None:
    raise KeyboardInterrupt


@contextmanager
def _interruptible():
    """Ctrl-C (SIGINT) and SIGTERM raise KeyboardInterrupt inside the block, whatever the process inherited
    (a parent that ignores SIGINT passes SIG_IGN on to its children, and an ignored Ctrl-C would leave the
    motor running until the episode's end); the previous handlers are restored afterwards, so a run called
    in-process (tests, notebooks) does not leave Ctrl-C ignored in the caller."""
    old = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


@rig_app.command("emulate")
@excludes("--model", "--params", why="the model file holds its base parameters")
@excludes("--model", "--add-effect", why="the model file holds its effects")
@excludes("--model", "--effect-param", why="the model file holds its effects' values")
@requires("--trust", "--model", why="it trusts the effect files a model file names")
def emulate_cmd(
    port: Path | None = typer.Option(None, help="also create a symlink to the pseudo-terminal here"),
    config: str = typer.Option("torsional", help="rig configuration: torsional, lateral or coupled"),
    params: Path | None = typer.Option(
        None,
        help="parameter file (JSON/YAML) of the emulated rig: RigParams or a model file with effects (identify --out)",
    ),
    add_effect: list[str] | None = add_effect_option(),
    effect_param: list[str] | None = effect_param_option(),
    model_file: Path | None = model_option(
        "model file (JSON/YAML, drillgym.Model: base parameters and effects, e.g. what `drillgym identify` wrote) "
        "the emulated plant runs, hidden from the host; not with --params, --add-effect or --effect-param"
    ),
    trust: bool = trust_option(),
    counts_per_rev: int | None = typer.Option(
        None, help="encoder counts per revolution [default: the encoders the --model file carries, else 8000]"
    ),
    lvdt_noise: float = typer.Option(3e-6, help="LVDT noise standard deviation (m)"),
    latency_ms: float = typer.Option(0.0, help="serial latency of every reply (ms)"),
    jitter_ms: float = typer.Option(0.0, help="extra uniform random latency up to this (ms)"),
    period_ms: float = typer.Option(10.0, help="default control period (ms); the host may change it"),
    watchdog_ms: float = typer.Option(100.0, help="motor to 0 V after this long without a command (ms)"),
    dt: float = typer.Option(1e-3, help="integration step of the emulated plant (s)"),
    alpha0: float = typer.Option(0.0, help="initial winding of the string (rad)"),
    seed: int = typer.Option(0, help="seed of the LVDT noise and latency jitter"),
    realtime: bool = typer.Option(
        True,
        "--realtime/--no-realtime",
        help="real-time scheduling (SCHED_FIFO) if permitted, else nice -10 as far as allowed",
    ),
) -> None:
    """Emulate the rig's microcontroller on a pseudo-terminal until Ctrl-C.  The plant runs the hidden
    effects (--add-effect, and those of a model file in --params), or the model of --model; the host does not
    know them."""
    from hw.emulator import RigEmulator
    from hw.firmware import FirmwareConfig

    _check_emulate_options(
        port, config, counts_per_rev, lvdt_noise, latency_ms, jitter_ms, period_ms, watchdog_ms, dt, alpha0, seed
    )
    base, comp, values, counts = emulated_plant(
        model_file, trust, config, params, add_effect, effect_param, counts_per_rev
    )
    fw = FirmwareConfig(counts_per_rev=counts, control_period_s=period_ms * 1e-3, watchdog_s=watchdog_ms * 1e-3)
    import time

    from hw.realtime import freeze_heap, prioritize

    def log(message: str) -> None:
        typer.echo(f"[{time.strftime('%H:%M:%S')}] {message}", err=True)

    import sys

    sys.setswitchinterval(5e-4)  # serial and timer threads share the interpreter: hand it over every 0.5 ms
    emu = RigEmulator(
        config,
        base,
        fw,
        effects=comp,
        effect_params=values,
        dt=dt,
        alpha0=alpha0,
        lvdt_noise_std=lvdt_noise,
        seed=seed,
        latency_s=latency_ms * 1e-3,
        jitter_s=jitter_ms * 1e-3,
        link_path=port,
        log=log,
    )
    # the libraries' heap out of the collector's reach (its pauses stay well below a control period), at normal
    # priority: the one full collection takes ~0.1 s of CPU, which at real-time priority would hold up other
    # real-time processes (another rig's host) as long
    freeze_heap()
    # before the threads start: they inherit it (the emulator stands in for a microcontroller)
    priority = prioritize(realtime)
    emu.start()
    log(f"emulator ready: watchdog {watchdog_ms:g} ms, scheduling priority {priority}")
    signal.signal(signal.SIGTERM, _interrupt)
    typer.echo(
        f"rig emulator ({config}) on {emu.port}"
        + (f" (link {port})" if port else "")
        + f"; {describe_plant(comp, values)}",
        err=False,
    )
    typer.echo("Ctrl-C to stop", err=True)
    try:
        emu.serve_forever()
    except KeyboardInterrupt:
        emu.stop()
    log(f"emulator stopped: {emu.timing_summary()}")


@rig_app.command("run")
@requires("--observation", "--policy", why="the observation of a linear policy")
@requires("--reconnect-wait", "--reconnect", when=lambda n: n > 0, what="--reconnect 1 or more")
@requires("--trust", "--model", why="it trusts the effect files a model file names")
def run_cmd(
    port: str = typer.Option(..., help="serial device or pyserial URL of the rig (or of `drillgym rig emulate`)"),
    controller: str | None = typer.Option(
        None,
        help="controller: const:<volts>, play:<input file> (an excitation "
        "from `drillgym signal`) or a name from controllers/",
    ),
    params: Path | None = typer.Option(
        None,
        help="base parameters the controller is built on (JSON/YAML, may be partial); default: the identified set "
        "(docs/model.md); a model file with effects goes to --model",
    ),
    model_file: Path | None = typer.Option(
        None,
        "--model",
        help="model file (base parameters and effects, e.g. from `drillgym diagnose --model-out`) the controller is "
        "built on: observer, lqg and lqg-2enc run its effects, and so does a trained agent on the observer base "
        "(agent:PATH or --policy); not with --params",
    ),
    trust: bool = typer.Option(
        False,
        "--trust",
        help="import the effect files the model file of --model names even when they lie outside its "
        "folder, carry no recorded hash or changed since it was written (an effect file is code: loading it runs it)",
    ),
    policy: Path | None = typer.Option(
        None,
        help="policy: what `drillgym train` writes (policy.npz, model.zip or the "
        "run directory; it builds its own observation from the encoders) or "
        "a linear .npz (W, b) on --observation",
    ),
    duration: float = typer.Option(10.0, help="episode length (s)"),
    record: Path = typer.Option(
        Path("rig_run.csv"),
        help="recording file (.csv, docs/data_format.md; replaced if it exists; later episodes: <name>_001.csv, "
        f"...) or a directory for timestamped recordings; checked before anything, also with --dry-run; {CREATES_DIRS}",
    ),
    config: str = typer.Option("torsional", help="how the rig is set up: torsional, lateral or coupled"),
    observation: str = typer.Option("sensors", help="policy observation: full, sensors or motor"),
    omega_ref: float | None = typer.Option(None, help="target lower-disc speed (rad/s); default drawn per seed"),
    control_ms: float = typer.Option(10.0, help="control period (ms)"),
    seed: int = typer.Option(0, help="episode seed"),
    reply_timeout_ms: float | None = typer.Option(
        None, help="longest wait for the firmware's reply (ms); default the firmware's watchdog (its CONFIG)"
    ),
    dry_run: bool = typer.Option(
        False,
        "--dry-run",
        help="check port, firmware, control period, controller or policy, limits and recording path; send no voltage",
    ),
    reconnect: int = typer.Option(
        0,
        help="after a lost link or a silent firmware, reopen the port and start a new "
        "episode (next recording file), at most this often",
    ),
    reconnect_wait: float = typer.Option(2.0, help="seconds to wait before reconnecting"),
    realtime: bool = typer.Option(
        True,
        "--realtime/--no-realtime",
        help="real-time scheduling (SCHED_FIFO) for the episode if permitted, else nice -10 as far as allowed",
    ),
) -> None:
    """Run one episode of a controller or a policy on the rig, recorded to --record.

    Exit code 0: the episode ran its course; 3: safety stop (watchdog, over-speed, e-stop, link
    fault), motor at 0 V, recording kept; 130: interrupted (Ctrl-C); 2: bad option, nothing moved.
    """
    import gymnasium as gym
    import numpy as np

    import hw
    from drillgym.commands.outputs import output_dir, output_file
    from hw.runner import load_policy, make_controller
    from hw.timing import PERCENTILES, percentile_summary

    from .rig_ops import dry_run as do_dry_run
    from .rig_ops import trained_agent, warm_up

    if (controller is None) == (policy is None):
        raise InputError("give exactly one of --controller or --policy")
    opts = _check_run_options(
        port, duration, record, config, observation, omega_ref, control_ms, seed, reply_timeout_ms, reconnect,
        reconnect_wait,
    )  # fmt: skip
    if controller is not None and controller.startswith("play:") and record.suffix.lower() == ".csv":
        from drillgym.io.outputs import check_not_inputs

        check_not_inputs(record, "--record", {"played input": controller[len("play:") :]})
    hw.register()
    # controller and policy first: a bad one is refused before the port is touched
    if policy is not None and not policy.exists():
        raise MissingFileError(
            f"--policy {policy} does not exist; give what `drillgym train` wrote (its run directory, policy.npz or "
            "model.zip) or a linear policy .npz (arrays W and b)"
        )
    if policy is not None and trained_agent(policy):  # a trained agent runs as the controller agent:PATH
        controller, policy = f"agent:{policy}", None
    model = None
    if params is not None:
        if controller is None or controller.startswith(("const:", "play:", "agent:")):
            raise InputError(
                "--params builds a named controller on a model; it does not apply to const:, play:, agent: or --policy"
            )
        from drillgym import RigParams
        from drillgym.commands.options import option

        with option("--params"):  # a model file with effects is refused: never half-read (give it as --model)
            model = RigParams.from_file(params)
    if model_file is not None:
        if params is not None or controller is None or controller.startswith(("const:", "play:")) or policy:
            raise InputError("--model builds a controller or a trained agent on a model file; not with --params, "
                             "const:, play: or a linear --policy")  # fmt: skip
        from controllers.model import model_of
        from drillgym.commands.options import option
        from drillgym.model import Model

        with option("--model"):
            model = model_of(Model.load(model_file, trust=trust))
            make_controller(controller, config, omega_ref, control_ms * 1e-3, model)  # refuses an unusable effect
    ctrl = make_controller(controller, config, omega_ref, control_ms * 1e-3, model) if controller else None
    if controller is not None and controller.startswith("agent:"):
        warm_up(ctrl, omega_ref, control_ms * 1e-3)
    pol = load_policy(policy) if policy is not None else None
    timeout = None if reply_timeout_ms is None else reply_timeout_ms * 1e-3

    def make_env():
        return gym.make(hw.ENV_ID, port=port, configuration=config, record=record, reply_timeout=timeout, **opts)

    def say(msg: str) -> None:
        typer.echo(msg, err=True)

    if dry_run:
        do_dry_run(make_env, ctrl, pol, record, typer.echo)
        return
    if record.suffix.lower() == ".csv":
        output_file(record)
    else:
        output_dir(record)
    notice = ClampNotice(say)
    with _interruptible():
        res, faults, watchdog_ms = _run_episode(
            make_env, ctrl, pol, seed, notice, realtime, reconnect, reconnect_wait, say
        )
    ms = 1e3
    typer.echo(
        f"{res.steps} steps, return {res.total_reward:.2f}, "
        f"{'terminated' if res.terminated else 'truncated' if res.truncated else 'stopped'}"
        + (f" (safety stop: {res.safety_stop})" if res.safety_stop else "")
    )
    if res.steps:
        rt = res.round_trips
        typer.echo(
            f"reply time (command sent -> its SAMPLE received) over {rt.size} commands: "
            f"{percentile_summary(np.percentile(rt, PERCENTILES), rt.max())}; "
            f"tick error p99 {ms * np.percentile(res.tick_errors, 99):.2f} ms, max {ms * res.tick_errors.max():.2f} ms"
        )
    if res.overruns:
        typer.echo(
            f"{res.overruns} of {res.steps} control periods overran (ran more than one period late): the loop did "
            f"not keep --control-ms {control_ms:g}"
        )
    if notice.count:
        typer.echo(f"{notice.count} of {res.steps} commands were clamped to the amplifier range")
    if faults:
        typer.echo(f"{len(faults)} link fault(s), reconnected; earlier episodes' recordings next to this one")
    typer.echo(f"recording: {res.recording}")
    why = stop_reason(res.safety_stop, watchdog_ms, res.terminated)
    if why is not None:
        say(f"drillgym: safety stop after {res.steps} steps: {why}; motor at 0 V, recording kept: {res.recording}")
        raise typer.Exit(STOP_EXIT)


@rig_app.command("estop")
def estop_cmd(
    port: str = typer.Option(..., help="serial device or pyserial URL of the rig"),
    attempts: int = typer.Option(3, help="send EMERGENCY_STOP up to this often until acknowledged"),
    timeout_ms: float = typer.Option(200.0, help="wait this long for each acknowledgement (ms)"),
) -> None:
    """Emergency stop: motor to 0 V now, latched (the next `rig run` handshake clears it).

    Works while another program runs the rig (that run then stops with a safety stop).
    Exit code 0 when the firmware acknowledged, 3 when it did not (check the rig).
    """
    from hw.checks import check_port, integer, number

    from .rig_ops import emergency_stop

    integer(attempts, "--attempts", low=1, high=100)
    number(timeout_ms, "--timeout-ms", low=0.0, high=1000.0, low_open=True, unit="ms")
    check_port(port, "--port")
    try:
        k = emergency_stop(port, attempts, timeout_ms * 1e-3)
    except SafetyError as exc:
        typer.echo(f"drillgym: {exc}", err=True)
        raise typer.Exit(STOP_EXIT) from None
    typer.echo(
        f"emergency stop acknowledged by the firmware on {port}"
        + (f" (attempt {k})" if k > 1 else "")
        + ": motor at 0 V, latched until the next `drillgym rig run`"
    )


def _run_episode(make_env, ctrl, pol, seed, notice, realtime, reconnect, reconnect_wait, say):
    """One episode on the rig: (result, link faults, the firmware's watchdog (ms)); exits 130 (interrupt)
    or 3 (safety stop) with one line, motor at 0 V."""
    from hw.realtime import prioritize, quiet_gc
    from hw.runner import run_episode

    from .rig_ops import run_with_reconnect

    env = None
    try:
        env = make_env()  # handshake and compiled kernels loaded at normal priority, then the episode's
        watchdog_ms = env.unwrapped.firmware.watchdog_ms
        with quiet_gc():  # its full collection at normal priority too: ~0.1 s that would hold up real-time work
            typer.echo(f"scheduling priority: {prioritize(realtime)}")
            res, faults = run_with_reconnect(
                env,
                lambda: run_episode(env, controller=ctrl, policy=pol, seed=seed, on_step=notice),
                reconnect,
                reconnect_wait,
                say,
            )
        return res, faults, watchdog_ms
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the stop short
        rec, acked = None, True
        if env is not None:
            env.close()  # ends the episode: EMERGENCY_STOP until acknowledged, recording flushed and closed
            rec, acked = env.unwrapped.recording, env.unwrapped.stop_acknowledged is not False
        motor = (
            "motor stopped (0 V)"
            if acked
            else "EMERGENCY_STOP not acknowledged by the firmware (its "
            f"watchdog stops the motor within {env.unwrapped.firmware.watchdog_ms} ms): check the rig"
        )
        say(f"drillgym: interrupted: {motor}, recording kept: {rec if rec is not None else 'none yet'}")
        raise typer.Exit(INTERRUPT_EXIT) from None
    except SafetyError as exc:
        if env is not None:
            env.close()
        say(f"drillgym: safety stop: {exc}")
        raise typer.Exit(STOP_EXIT) from None
    finally:
        if env is not None:
            env.close()


def _check_config(config: str, option: str = "--config") -> str:
    from drillgym.envs.options import _ENV_CONFIGURATIONS

    names = [c.name.lower() for c in _ENV_CONFIGURATIONS]
    if config.strip().lower().replace("-", "_") not in names:
        raise InputError(f"{option} {config!r}: not a rig configuration; use one of {', '.join(names)}")
    return config


def _check_run_options(
    port, duration, record, config, observation, omega_ref, control_ms, seed, reply_timeout_ms, reconnect, wait
) -> dict:
    """Every option of ``rig run`` checked before anything is built or opened; the environment's options."""
    from drillgym.envs.options import OBSERVATION_MODES, EnvOptions
    from hw.checks import check_port, check_record_path, integer, number

    number(duration, "--duration", low=0.0, low_open=True, unit="s")
    number(control_ms, "--control-ms", low=0.0, high=1000.0, low_open=True, unit="ms")
    if duration < control_ms * 1e-3:
        raise InputError(f"--duration {duration:g} s is shorter than one control period (--control-ms {control_ms:g})")
    _check_config(config)
    if observation not in OBSERVATION_MODES:
        raise InputError(f"--observation {observation!r}: use one of {', '.join(OBSERVATION_MODES)}")
    if omega_ref is not None:
        number(omega_ref, "--omega-ref", low=0.0, low_open=True, unit="rad/s")
    integer(seed, "--seed", low=0, high=2**32 - 1)
    if reply_timeout_ms is not None:
        number(reply_timeout_ms, "--reply-timeout-ms", low=0.0, high=1000.0, low_open=True, unit="ms")
    integer(reconnect, "--reconnect", low=0)
    number(wait, "--reconnect-wait", low=0.0, high=3600.0, unit="s")
    check_port(port, "--port")
    check_record_path(record, "--record")
    opts = {"observation": observation, "episode_duration": duration, "control_dt": control_ms * 1e-3}
    if omega_ref is not None:
        opts["omega_ref"] = omega_ref
    names = {"omega_ref": "--omega-ref", "episode_duration": "--duration", "control_dt": "--control-ms"}
    try:
        EnvOptions.from_kwargs(configuration=config, lvdt_noise_std=0.0, **opts)
    except InputError as exc:  # the environment's own limits (e.g. omega_ref beyond max_speed), named as options
        msg = str(exc)
        for name, option in names.items():
            msg = msg.replace(f"option '{name}'", option)
        raise InputError(msg) from None
    return opts


def emulated_plant(model_file, trust, config, params, add_effect, effect_param, counts_per_rev):
    """``rig emulate``'s plant: (base RigParams, Composition, effect values, encoder counts/rev).  The model of
    ``model_file``, or the parameters and hidden effects of ``params`` and ``add_effect``; the encoders' counts are
    ``counts_per_rev`` when given, else the model's encoders' (what ``identify`` read off the recording), else
    8000."""
    from drillgym.configurations import parse_configuration
    from drillgym.measurement import DEFAULT_COUNTS_PER_REV

    counts = DEFAULT_COUNTS_PER_REV
    if model_file is not None:
        m = model_from_cli(
            model_file, trust, parse_configuration(config), params=params, add_effect=add_effect,
            effect_param=effect_param,
        )  # fmt: skip
        base, comp, values = m.params, m.composition, dict(m.values)
        if m.encoders is not None:  # the count the controllers built on the model are told, where known
            counts = m.encoders.controller_keywords().get("counts_per_rev", counts)
    else:
        base, comp, values = plant_from_cli(params, add_effect, effect_param, configs=(parse_configuration(config),))
    return base, comp, values, counts if counts_per_rev is None else counts_per_rev


def _check_emulate_options(
    port, config, counts_per_rev, lvdt_noise, latency_ms, jitter_ms, period_ms, watchdog_ms, dt, alpha0, seed
) -> None:
    """Every option of ``rig emulate`` checked before the plant is built or the pseudo-terminal opened."""
    from drillgym.io.outputs import check_creatable
    from hw.checks import integer, number
    from hw.emulator import check_link_path

    if port is not None:
        if not str(port).strip():
            raise InputError("--port: an empty path; give a path for the link to the pseudo-terminal")
        check_link_path(port)
        if not port.is_symlink():
            check_creatable(port, "--port", "link")
    _check_config(config)
    if counts_per_rev is not None:
        integer(counts_per_rev, "--counts-per-rev", low=1, high=2**31 - 1)
    number(lvdt_noise, "--lvdt-noise", low=0.0, high=1.0, unit="m")
    number(latency_ms, "--latency-ms", low=0.0, high=60000.0, unit="ms")
    number(jitter_ms, "--jitter-ms", low=0.0, high=60000.0, unit="ms")
    number(period_ms, "--period-ms", low=0.0, high=60000.0, low_open=True, unit="ms")
    number(watchdog_ms, "--watchdog-ms", low=1.0, high=65535.0, unit="ms (CONFIG carries it in whole ms)")
    number(dt, "--dt", low=1e-6, high=period_ms * 1e-3, unit="s (at most the control period, --period-ms)")
    n = round(period_ms * 1e-3 / dt)
    if abs(n * dt - period_ms * 1e-3) > 1e-9:
        raise InputError(f"--period-ms {period_ms:g} is not a whole number of plant steps (--dt {dt:g} s)")
    number(alpha0, "--alpha0", low=-100.0, high=100.0, unit="rad")
    integer(seed, "--seed", low=0, high=2**32 - 1)
