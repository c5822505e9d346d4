"""The agents' commands of the ``drillgym`` CLI: train, combine-policies, average-policies and benchmark.

``drillgym train`` trains an RL agent (stable-baselines3) on a drillgym environment;
``--add-effect``/``--effect-param`` train on rigs with those effects (the env options
``effects``/``effect_params``, saved in config.yml by spec), ``--model FILE`` on rigs running that
model (``drillgym.Model``; recorded in config.yml). ``drillgym combine-policies`` joins
trained networks into one target-switched policy, ``drillgym average-policies`` networks of one recipe into
their mean (:mod:`agents.ensemble`). ``drillgym benchmark`` scores a policy on a named task
(:mod:`agents.benchmark_command`).

The CLI finds :func:`register` through the ``drillgym.commands`` entry-point group
(``pyproject.toml``); the training stack (torch, stable-baselines3) loads only when a command runs.
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import typer

from drillgym.commands.effect_options import (
    add_effect_option,
    effect_param_option,
    effects_from_cli,
    model_option,
    trust_option,
)
from drillgym.commands.options import excludes, requires
from drillgym.errors import InputError


def process_seconds() -> float:
    """Wall-clock seconds since this process started.

    Interpreter start-up and imports are included: what the user waits.

    Returns
    -------
    float
        Seconds since the process started (from ``/proc``), or, where ``/proc`` cannot be read,
        since this module was imported.
    """
    import os
    import time

    try:
        ticks = int(open("/proc/self/stat").read().rsplit(")", 1)[1].split()[19])
        uptime = float(open("/proc/uptime").read().split()[0])
        return uptime - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return time.perf_counter() - _IMPORTED


_IMPORTED = __import__("time").perf_counter()


@contextmanager
def _train_errors(overrides: list[str]) -> Iterator[None]:
    """Name the option behind a refusal the learners raise at their start: a ``--set`` key the algorithm
    or the environment does not take, a ``--teacher`` that cannot be distilled, an ``--init`` policy that does
    not fit the run."""
    from drillgym.commands.options import named

    keys = [o.partition("=")[0].strip() for o in overrides]
    try:
        yield
    except InputError as exc:
        msg = str(exc)
        if msg.startswith("init "):  # agents.finetune: the init policy does not fit this run
            raise named("--init", exc) from exc
        if "environment option" in msg or "hyperparameter" in msg:
            raise named("--set", exc) from exc
        if msg.startswith("a teacher") or "teacher" in msg.split(":", 1)[0]:
            raise named("--teacher", exc) from exc
        raise
    except TypeError as exc:  # the algorithm's constructor refuses a key it does not know
        bad = next((k for k in keys if f"'{k.split('.')[-1]}'" in str(exc)), None)
        if bad is None or "unexpected keyword argument" not in str(exc):
            raise
        raise InputError(f"--set {bad}: not a hyperparameter of this algorithm ({exc})") from None


def _policy_files(policies: list[Path]) -> list[Path]:
    """The ``policy.npz`` of each argument (a file, or a run directory holding one), each checked to be one."""
    from drillgym.errors import MissingFileError

    files = [p / "policy.npz" if p.is_dir() else p for p in policies]
    for f in files:
        if not f.is_file():
            raise MissingFileError(f"POLICIES: {f} not found (a policy.npz or a run directory holding one)")
        _check_npz(f)
    return files


def _check_npz(path: Path, option: str = "POLICIES") -> None:
    """Refuse, naming ``option`` and ``path``, a file numpy cannot open as an .npz archive."""
    import zipfile

    import numpy as np

    if not zipfile.is_zipfile(path):
        raise InputError(f"{option}: {path} is not an exported policy: not an .npz archive")
    try:
        with np.load(path, allow_pickle=False) as archive:
            archive.files  # noqa: B018 - opening the index is the check
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        why = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise InputError(f"{option}: {path} is not an exported policy (.npz): {why}") from None


def register(app: typer.Typer) -> None:
    """Add ``train``, ``combine-policies`` and ``benchmark`` to the ``drillgym`` application.

    Parameters
    ----------
    app : typer.Typer
        The ``drillgym`` command-line application.
    """
    from agents.benchmark_command import register_benchmark

    register_benchmark(app)

    @app.command("train")
    @requires("--workers", "--seeds", when=lambda n: n > 1, what="--seeds 2 or more", why="seeds trained at once")
    @excludes("--teacher", "--resume", why="a resumed run continues its RL steps; the teacher taught at its start")
    @excludes("--init", "--resume", why="a resumed run continues from its own checkpoint")
    @requires("--teacher", "--algo", when=lambda a: a.lower() == "ppo", what="--algo ppo", why="distilled into PPO")
    @excludes("--model", "--add-effect", why="the model file holds its effects")
    @excludes("--model", "--effect-param", why="the model file holds its effects' values")
    @requires("--trust", "--model", why="it trusts the effect files a model file names")
    def train_cmd(
        env: str = typer.Option(
            "drillgym/Torsional-v0",
            "--env",
            help="environment id, or a benchmark task id (drillgym/Population-Motor-v0, ...: "
            "its fixed options and training plants; see docs/benchmark.md)",
        ),
        algo: str = typer.Option("sac", "--algo", help="ppo, sac, td3 or recurrentppo"),
        out: Path = typer.Option(
            ...,
            "--out",
            help="run directory (model.zip, policy.npz, config.yml, tb/, "
            "checkpoints/); missing directories are created",
        ),
        obs: str | None = typer.Option(
            None, "--obs", help="observation mode: full, sensors, motor (default: the hyperparameter file's)"
        ),
        timesteps: int | None = typer.Option(
            None, "--timesteps", help="environment steps (default: the file's n_timesteps)"
        ),
        seed: int = typer.Option(0, "--seed", help="seed of networks, exploration and envs (with --seeds: the first)"),
        seeds: int = typer.Option(
            1,
            "--seeds",
            help="train this many seeds (SEED, SEED+1, ...) into OUT/seed_<s>/, in "
            "parallel where cores allow; writes OUT/results.csv, OUT/results.md (per-seed lowest "
            "held target, returns; IQM with bootstrap 95 % interval) and "
            "OUT/learning_curves.png",
        ),
        workers: int | None = typer.Option(
            None, "--workers", help="seeds trained at once (default: min(seeds, CPU cores))"
        ),
        ray: str | None = typer.Option(
            None,
            "--ray",
            help="with --seeds: train them as Ray Tune trials on 'auto' (a "
            "running cluster), 'local' (start one here) or HOST:PORT",
        ),
        eval_every: int | None = typer.Option(
            None,
            "--eval-every",
            help="environment steps between evaluations of the "
            "deterministic policy; the best is kept in OUT/best/ (0 = none; "
            "default: a twentieth of the run, at least 10000)",
        ),
        n_envs: int | None = typer.Option(None, "--n-envs", help="rigs in the batched vector env"),
        hyperparams: Path | None = typer.Option(
            None, "--hyperparams", help="YAML file (rl-zoo3 layout) instead of agents/hyperparams/<algo>.yml"
        ),
        set_: list[str] | None = typer.Option(
            None,
            "--set",
            help="override a hyperparameter, KEY=VALUE (YAML value; env options as env_kwargs.NAME=VALUE), repeatable",
        ),
        resume: bool = typer.Option(False, "--resume", help="continue from OUT/checkpoints/latest.zip"),
        checkpoint_every: int = typer.Option(
            50_000, "--checkpoint-every", help="environment steps between checkpoints"
        ),
        progress: bool = typer.Option(True, "--progress/--no-progress", help="progress bar"),
        tensorboard: bool = typer.Option(True, "--tensorboard/--no-tensorboard", help="TensorBoard logs in OUT/tb"),
        teacher: Path | None = typer.Option(
            None,
            "--teacher",
            help="policy.npz of a run on the 'full' observation, or a teacher's name (flatness, lqg-2enc, observer): "
            "distilled (DAgger) into this run's network before the RL steps "
            "(--timesteps 0: distillation only)",
        ),
        add_effect: list[str] | None = add_effect_option(),
        effect_param: list[str] | None = effect_param_option(),
        model_file: Path | None = model_option(
            "model file (JSON/YAML, drillgym.Model, e.g. what `drillgym identify` wrote) every training rig runs "
            "(on a task id: the task's nominal model, a population task's plants drawn around it); not with "
            "--add-effect, --effect-param or env_kwargs params/effects"
        ),
        trust: bool = trust_option(),
        init: Path | None = typer.Option(
            None,
            "--init",
            help="start from the weights of this run directory's model.zip (a kept policy; the same --algo, "
            "observation and network) instead of a fresh network; with --model: a policy adapted to that rig",
        ),
    ) -> None:
        """Train an agent; writes OUT/model.zip, OUT/policy.npz (for agent:PATH in `drillgym evaluate`),
        OUT/config.yml."""
        from agents.hyperparams import parse_overrides
        from agents.train import train
        from drillgym.commands.options import option
        from drillgym.commands.outputs import check_not_inputs, check_output_dir
        from drillgym.configurations import parse_configuration
        from drillgym.envs import ENV_IDS
        from drillgym.errors import MissingFileError

        check_output_dir(out)
        check_not_inputs(out, "--out", {"--init run": init, "--teacher policy": teacher})
        from agents.task_training import configuration_of, is_task
        from drillgym.envs.tasks import TASKS

        if env not in ENV_IDS and not is_task(env):
            raise InputError(f"--env must be one of {', '.join(ENV_IDS)} or a task ({', '.join(TASKS)}), got {env!r}")
        if is_task(env) and (add_effect or effect_param):
            raise InputError(f"--add-effect/--effect-param: task {env} fixes its plants (train on a free env id)")
        from agents.train import ALGOS

        if algo not in ALGOS:
            raise InputError(f"--algo must be one of {', '.join(ALGOS)}, got {algo!r}")
        if obs is not None and obs not in ("full", "sensors", "motor"):
            raise InputError(f"--obs must be full, sensors or motor, got {obs!r}")
        if timesteps is not None and (timesteps < 0 or (timesteps == 0 and teacher is None)):
            raise InputError(f"--timesteps must be >= 1 (0 only with --teacher: distillation only), got {timesteps}")
        if seed < 0:
            raise InputError(f"--seed must be >= 0, got {seed}")
        if workers is not None and workers < 1:
            raise InputError(f"--workers must be >= 1, got {workers}")
        from agents.teachers import TEACHERS

        if teacher is not None and str(teacher) in TEACHERS:  # a teacher by name, not a file
            teacher = str(teacher)
        for opt, path in (("--hyperparams", hyperparams), ("--teacher", teacher)):
            if isinstance(path, Path) and not path.is_file():
                raise MissingFileError(f"{opt} {path}: {'a directory' if path.is_dir() else 'file not found'}")
        if hyperparams is not None:
            try:
                hyperparams.read_text(encoding="utf-8")
            except UnicodeDecodeError as exc:
                raise InputError(
                    f"--hyperparams {hyperparams}: not UTF-8 text (byte {exc.start}); give a YAML file"
                ) from None
        if isinstance(teacher, Path):
            _check_npz(teacher, "--teacher")
            from agents.export import ExportedPolicy

            with option("--teacher"):  # the teacher reads the true state: refused now, not after the rigs are built
                taught = ExportedPolicy.load(teacher).config.get("hyperparams", {}).get("env_kwargs", {})
            if taught.get("observation", "full") != "full":
                raise InputError(
                    f"--teacher {teacher}: trained on the {taught['observation']!r} observation; a teacher is a "
                    "policy of the 'full' observation (the true state)"
                )
        if init is not None:
            from agents.finetune import init_model_file

            with option("--init"):
                init_model_file(init)
        if ray is not None:
            from drillgym.parallel import check_ray_address

            check_ray_address(ray)
        if n_envs is not None and n_envs < 1:
            raise InputError(f"--n-envs must be >= 1, got {n_envs}")
        if checkpoint_every < 1:
            raise InputError(f"--checkpoint-every must be >= 1, got {checkpoint_every}")
        if seeds < 1:
            raise InputError(f"--seeds must be >= 1, got {seeds}")
        if eval_every is not None and eval_every < 0:
            raise InputError(f"--eval-every must be >= 0, got {eval_every}")
        command = "drillgym " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        with option("--set"):
            overrides = parse_overrides(set_ or [])
        if model_file is not None:  # read now: a bad file is refused in one line before training
            from drillgym.commands.effect_options import model_from_cli

            model_from_cli(model_file, trust, parse_configuration(configuration_of(env)))
            clash = [k for k in ("params", "effects", "effect_params") if k in overrides.get("env_kwargs", {})]
            if clash:
                raise InputError(f"--model cannot go with --set env_kwargs.{clash[0]} (the model file holds its own)")
        if add_effect or effect_param:
            cfg = parse_configuration(configuration_of(env))
            comp, values = effects_from_cli(add_effect, effect_param, cfg)  # one-line errors before training
            env_kw = overrides.setdefault("env_kwargs", {})
            env_kw.update(effects=comp.specs(), effect_params=dict(values))
        if eval_every is None:  # a twentieth of the run, at least 10,000 steps apart
            from agents.train import planned_timesteps

            with option("--hyperparams" if hyperparams is not None else "--env"):
                eval_every = max(10_000, planned_timesteps(env, algo, timesteps, hyperparams, overrides) // 20)
        kw = dict(
            obs=obs,
            timesteps=timesteps,
            n_envs=n_envs,
            hyperparams=hyperparams,
            overrides=overrides,
            resume=resume,
            tensorboard=tensorboard,
            checkpoint_every=checkpoint_every,
            command=command,
            eval_every=eval_every,
            teacher=teacher,
        )
        if model_file is not None:  # the path, not the Model: seeds may train in other processes
            kw.update(model=str(model_file), trust=trust)
        if init is not None:
            kw.update(init=str(init))
        if seeds > 1 or ray:  # several seeds, or seeds on Ray: one summary over them
            from agents.seeds import train_seeds

            with _train_errors(set_ or []):
                summary = train_seeds(env, algo, out, list(range(seed, seed + seeds)), workers=workers, ray=ray, **kw)
            held = summary.aggregates.get("lowest_held")
            typer.echo(
                f"trained {seeds} seeds in {process_seconds():.1f} s wall clock since the command started; "
                f"wrote {out / 'results.md'}, "
                f"{out / 'learning_curves.png'}"
                + (
                    f"; lowest held target IQM {held['iqm']:.2f} rad/s [{held['ci_low']:.2f}, {held['ci_high']:.2f}]"
                    if held
                    else ""
                )
            )
            return
        with _train_errors(set_ or []):
            res = train(env, algo, out, seed=seed, progress=progress, **kw)
        typer.echo(
            f"trained {res.timesteps} steps in {process_seconds():.1f} s wall clock since the command started "
            f"({res.wall_time:.1f} s of them learning); wrote {res.model_path}"
            + (f", {res.policy_path}" if res.policy_path else "")
            + (f"; best evaluated model in {out / 'best'}" if eval_every else "")
        )

    @app.command("combine-policies")
    def combine_cmd(
        policies: list[Path] = typer.Argument(
            ..., help="exported networks (policy.npz or run directories), the lowest target band first"
        ),
        edges: str = typer.Option(
            ...,
            "--edges",
            help="target speeds (rad/s) where one network hands over to the "
            "next, comma-separated, increasing (one fewer than networks)",
        ),
        out: Path = typer.Option(
            ..., "--out", help="the target-switched policy (.npz); missing directories are created"
        ),
        note: str = typer.Option("", "--note", help="free text stored with the policy (why these bands)"),
    ) -> None:
        """Combine learned networks into one policy that gives each target to the network of its band
        (network k serves EDGE[k-1] <= target < EDGE[k]); runs wherever a policy.npz does."""
        from agents.switched import combine

        try:
            cuts = [float(v) for v in edges.split(",") if v.strip()]
        except ValueError:
            raise InputError(f"--edges must be speeds in rad/s separated by commas, got {edges!r}") from None
        import math

        from drillgym.commands.options import option
        from drillgym.commands.outputs import check_not_inputs, check_output_file

        if not cuts or not all(math.isfinite(c) and c > 0 for c in cuts) or cuts != sorted(set(cuts)):
            raise InputError(f"--edges must be increasing positive finite speeds (rad/s), got {edges!r}")
        check_output_file(out, "--out", suffixes=(".npz",))
        files = _policy_files(policies)
        check_not_inputs(out, "--out", {f"network {i}": f for i, f in enumerate(files)})
        with option("POLICIES"):  # its missing directories created once the networks are checked, as --help says
            path = combine(files, cuts, out, note=note)
        typer.echo(f"wrote {path}: {len(files)} networks, handing over at {', '.join(f'{c:g}' for c in cuts)} rad/s")

    @app.command("average-policies")
    def average_cmd(
        policies: list[Path] = typer.Argument(
            ..., help="exported networks of one recipe (policy.npz or run directories), seeds differing"
        ),
        out: Path = typer.Option(..., "--out", help="the averaged network (.npz); missing directories are created"),
    ) -> None:
        """Average networks of one recipe into one wider network whose action is the mean of theirs (before the
        output clip); runs wherever a policy.npz does (agents/ensemble.py)."""
        from agents.ensemble import average
        from drillgym.commands.options import option
        from drillgym.commands.outputs import check_not_inputs, check_output_file

        check_output_file(out, "--out", suffixes=(".npz",))
        files = _policy_files(policies)
        check_not_inputs(out, "--out", {f"network {i}": f for i, f in enumerate(files)})
        with option("POLICIES"):  # its missing directories created once the networks are checked
            path = average(files, out)
        typer.echo(f"wrote {path}: the mean of {len(files)} networks")
