"""``drillgym rig tune``: identify the rig, then hand the model to its controllers.

One command runs what the lab does by hand before a model-based controller goes on the rig:

1. an **excitation run** on the rig: the quasi-random estimation signal (:func:`drillgym.signals.quasi_random`,
   0-5 V) played through ``drillgym/Hardware-v0`` exactly as ``rig run --controller play:FILE`` plays it (the
   safety limits, the watchdog and the recording are the same), recorded to ``--record``;
2. **identification** of that recording by :func:`drillgym.identify`, the one front every route takes
   (``diagnose --model-out``, ``drillgym identify``, ``evaluate --identify``): the library's effects the
   recording shows, a candidate outside the library when one earns its place, and the base parameters and
   every effect fitted together with their standard errors;
3. the **model file** (``--model-out``) that ``rig run --model``, ``evaluate --model`` and
   ``controllers.make(..., model=)`` read, and, per target speed, the model accuracy a motor-angle-only
   controller needs there against what the identification achieved (:mod:`controllers.margin`).

Exit codes as ``rig run``: 0 done, 3 safety stop during the excitation (motor at 0 V, recording kept, no model
written), 130 interrupted, 2 bad option (nothing moved).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import typer

from drillgym.errors import InputError

from .rig_ops import STOP_EXIT, ClampNotice, stop_reason

__all__ = ["tune_cmd", "MARGIN_TARGETS"]

#: target speeds (rad/s) whose model margin ``rig tune`` prints
MARGIN_TARGETS = (1.0, 1.5, 2.0, 2.5, 3.0)


def tune_cmd(
    port: str = typer.Option(..., help="serial device or pyserial URL of the rig (or of `drillgym rig emulate`)"),
    model_out: Path = typer.Option(
        ..., "--model-out", help="model file written (.json, .yaml or .yml): base parameters, effects, standard errors"
    ),
    record: Path = typer.Option(
        Path("rig_tune.csv"), help="recording of the excitation run (.csv, docs/data_format.md; replaced if it exists)"
    ),
    duration: float | None = typer.Option(
        None, help="length of the excitation (s); default 60 torsional, 30 coupled (evaluate --identify's)"
    ),
    control_ms: float = typer.Option(2.0, help="control period (ms): the signal's sample time and the recording's"),
    config: str = typer.Option("torsional", help="how the rig is set up: torsional or coupled"),
    seed: int = typer.Option(0, help="seed of the excitation signal"),
    realtime: bool = typer.Option(
        True,
        "--realtime/--no-realtime",
        help="real-time scheduling (SCHED_FIFO) for the episode if permitted, else nice -10 as far as allowed",
    ),
) -> None:
    """Identify the rig: an excitation run, diagnose and identify on it, and the model file its controllers read.

    Exit code 0: the model was written; 3: safety stop during the excitation (motor at 0 V, recording kept,
    no model); 130: interrupted; 2: bad option (nothing moved).
    """
    import gymnasium as gym

    import hw
    from drillgym.io.outputs import check_output_file, output_file
    from drillgym.signals import quasi_random, write_input_file
    from hw.checks import check_record_path
    from hw.runner import make_controller

    from .rig import _check_run_options, _interruptible, _run_episode

    if config not in ("torsional", "coupled"):
        raise InputError(f"--config {config!r}: rig tune identifies the torsional or the coupled set-up")
    if record.suffix.lower() != ".csv":
        raise InputError(f"--record {record}: the excitation's recording must be one .csv file")
    check_record_path(record, "--record")
    suffixes = (".json", ".yaml", ".yml")
    if model_out.suffix.lower() not in suffixes:
        raise InputError(f"--model-out {model_out}: a model file must end in .json, .yaml or .yml")
    check_output_file(model_out, "--model-out", suffixes=suffixes)
    if duration is None:
        from controllers.evaluation.identify import EXCITATION_S

        duration = EXCITATION_S[config]
    opts = _check_run_options(port, duration, record, config, "motor", None, control_ms, seed, None, 0, 0.0)
    rate = 1e3 / control_ms
    from drillgym.signals import check_signal

    try:  # the excitation's settings, before anything is created
        check_signal(duration, rate, 5.0, 2.5, seed, names={"duration": "--duration", "seed": "--seed"})
    except InputError as exc:
        if "rate_hz" not in str(exc):
            raise
        why = str(exc).replace("lower rate_hz", "lengthen --control-ms").replace("rate_hz", "the rate")
        raise InputError(f"--control-ms {control_ms:g} (the excitation sampled at {rate:g} Hz): {why}") from None
    hw.register()
    output_file(record, "--record")
    with tempfile.TemporaryDirectory(prefix="drillgym_tune_") as tmp:
        t, u = quasi_random(duration, rate_hz=rate, seed=seed, amplitude=5.0, offset=2.5)
        signal_file = write_input_file(Path(tmp) / "excitation.csv", t, u, "rig tune: quasi-random excitation")
        ctrl = make_controller(f"play:{signal_file}", config, None, control_ms * 1e-3)

        def make_env():
            return gym.make(hw.ENV_ID, port=port, configuration=config, record=record, **opts)

        def say(msg: str) -> None:
            typer.echo(msg, err=True)

        with _interruptible():
            res, _, watchdog_ms = _run_episode(make_env, ctrl, None, seed, ClampNotice(say), realtime, 0, 0.0, say)
    why = stop_reason(res.safety_stop, watchdog_ms, res.terminated)
    if why is not None:
        say(f"drillgym: safety stop during the excitation after {res.steps} steps: {why}; motor at 0 V, recording "
            f"kept: {res.recording}; no model written")  # fmt: skip
        raise typer.Exit(STOP_EXIT)
    typer.echo(f"excitation: {res.steps} steps of {control_ms:g} ms recorded to {res.recording}")
    _identify_and_write(Path(res.recording), model_out, typer.echo)


def _identify_and_write(recording: Path, model_out: Path, echo) -> None:
    """Identify a recording (:func:`drillgym.identify`, as every route), write the model file, print what was
    found and the margins."""
    from controllers.margin import model_margins
    from drillgym import RigParams, identify
    from drillgym.diagnosis.information import CannotTellError
    from drillgym.io.outputs import output_file

    try:
        found = identify(recording)
    except CannotTellError as exc:  # no model from a recording that cannot carry one
        raise CannotTellError(f"{exc}; recording kept: {recording}; no model written") from None
    m = found.model
    path = m.save(output_file(model_out, "--model-out"))
    nominal = RigParams()
    moved = ", ".join(
        f"{k} {100 * (getattr(m.params, k) / v - 1):+.2f} %"
        for k, v in nominal.to_dict().items()
        if v and abs(getattr(m.params, k) / v - 1) >= 0.005
    )
    effects = ", ".join(f"{k} = {v:.4g}" for k, v in m.values.items()) or "none"
    echo(f"identified in {found.seconds:.1f} s: effects {m.label} ({effects})")
    echo(f"base parameters off the identified set: {moved or 'none by 0.5 % or more'}")
    for w in found.warnings:
        echo(f"warning: {w}")
    for margin in model_margins(m, MARGIN_TARGETS):
        echo(margin.line("a motor-angle-only controller"))
    echo(f"model: {path} (drillgym rig run --controller observer --model {path} ...)")
