"""The command-line contract, generated from the command tree: what every command owes a user on any input.

Every command and subcommand of ``drillgym`` (the typer tree, introspected: a command added tomorrow is
covered without a line here) is run in this process on command lines drawn by Hypothesis: its options and
arguments set to values of the wrong type, negative, NaN, infinite, empty, missing files, directories where
files are expected, garbage files, existing or unwritable output paths, and options that mean something only
beside another given alone (the table of :mod:`drillgym.commands.options`). The contract:

* exit 0 with valid outputs (strict JSON, finite numbers, files that read back), or exit 2 with ONE line
  ``drillgym: error: ...`` naming what is wrong; never a traceback;
* no file changed or created outside the outputs named on the command line, and on a refusal none at all
  (every check passes before the first file is written).

To stay quick, commands that run long on valid input (:data:`EXPENSIVE`, and any command not in
:data:`BASES`) are always drawn with at least one value that must be refused; the cheap ones also run valid.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import os
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import typer

from drillgym.cli import app, main

#: what a refusal exits with
USER_ERROR = 2
#: the sentence the --help of every written path holds (drillgym.commands.outputs.CREATES_DIRS)
CREATES = "missing directories are created"
#: seconds a case may take: a refused value is refused at once; a wrongly accepted one would run on
CASE_SECONDS = 30


# --------------------------------------------------------------------------------------- the command tree


@dataclass(frozen=True)
class Param:
    """One option or argument of a command, as the contract sees it."""

    name: str  # the option string (--out) or the argument's name in capitals (DATA)
    kind: str  # "int", "float", "str", "path", "flag"
    argument: bool
    multiple: bool
    required: bool
    output: bool  # a path the command writes
    directory: bool  # a directory (output directory, or an input that may be one)
    help: str
    default: object
    secondary: str = ""  # the off switch of a --x/--no-x flag


def _kind(annotation) -> tuple[str, bool]:
    """(kind, multiple) of a parameter's annotation."""
    text = str(annotation)
    multiple = text.startswith("list[") or text.startswith("typing.List")
    for word, kind in (("bool", "flag"), ("int", "int"), ("float", "float"), ("Path", "path"), ("str", "str")):
        if word in text:
            return kind, multiple
    return "str", multiple


def _param(p) -> Param:
    kind, multiple = _kind(p.type_descriptor.annotation)
    help_ = " ".join((getattr(p, "help", "") or "").split())
    argument = type(p).__name__ == "TyperArgument"
    name = (p.name or "").upper() if argument else max(p.opts, key=len)
    words = help_.lower()
    output = kind == "path" and (
        CREATES in words
        or any(w in words for w in ("write", "written", "create a symlink", "recording file", "recording of the"))
    )
    directory = "directory" in words or "directories" in words.replace(CREATES, "")
    if kind == "flag" and not getattr(p, "is_flag", True):
        kind = "str"
    return Param(
        name,
        kind,
        argument,
        multiple or bool(getattr(p, "multiple", False)) or (argument and getattr(p, "nargs", 1) == -1),
        bool(p.required),
        output,
        directory,
        help_,
        p.default,
        (p.secondary_opts[0] if getattr(p, "secondary_opts", None) else ""),
    )


@dataclass(frozen=True)
class Command:
    path: tuple[str, ...]
    params: tuple[Param, ...]
    dependencies: tuple  # drillgym.commands.options.Dependency


def commands() -> list[Command]:
    """Every leaf command of the ``drillgym`` tree with its parameters and declared dependencies."""
    from drillgym.commands.options import dependencies_of

    out: list[Command] = []

    def walk(cmd, path: tuple[str, ...]) -> None:
        subs = getattr(cmd, "commands", None)
        if subs is not None:
            for name in sorted(subs):
                walk(subs[name], (*path, name))
            return
        params = tuple(_param(p) for p in cmd.params if p.name not in ("help",))
        out.append(Command(path, params, dependencies_of(cmd.callback)))

    walk(typer.main.get_command(app), ())
    return out


# --------------------------------------------------------------------------------------- the assets


@dataclass(frozen=True)
class Assets:
    """Input files a case may name (never to be changed), built once."""

    root: Path

    def __getattr__(self, name: str) -> str:  # a.torsional -> .../torsional.csv (the bad-inputs names), a.p1 -> .../p1
        from bad_inputs import Assets as Named

        try:
            return getattr(Named(self.root), name)
        except AttributeError:
            return str(self.root / name)


def build_assets(root: Path) -> Assets:
    """The bad-inputs assets (recordings of 0.2 s, garbage files, a directory, hostile model files) and two members
    of one recipe (a kept policy and a copy with other weights), a policy with a NaN weight and one of the wrong
    shape."""
    import shutil

    from bad_inputs import build_assets as bad_input_assets

    bad_input_assets(root)
    kept = Path(__file__).resolve().parents[1] / "agents" / "policies" / "population_motor_distilled_mean"
    shutil.copy(kept / "policy.npz", root / "p1.npz")
    z = dict(np.load(root / "p1.npz"))
    z2 = {k: (v * 1.01).astype(v.dtype) if k.startswith("W") else v for k, v in z.items()}
    np.savez(root / "p2.npz", **z2)
    nan = dict(z)
    nan["W0"] = nan["W0"].copy()
    nan["W0"][0, 0] = np.nan
    np.savez(root / "nan_policy.npz", **nan)
    shape = dict(z)
    shape["W1"] = shape["W1"][:, :-1]
    np.savez(root / "shape_policy.npz", **shape)
    (root / "model.json").write_text(json.dumps({"effects": [{"spec": "motor_lag", "values": {"tau_m": 0.04}}]}))
    from bad_inputs import build_hostile_models

    build_hostile_models(root)  # models/NAME.json: model files with one thing wrong
    return Assets(root)


# --------------------------------------------------------------------------------------- the bases

#: a command line of each known command that is valid, or nearly (``{A}``: the assets directory, ``{P1}``, ``{P2}``)
BASES: dict[tuple[str, ...], list[str]] = {
    ("simulate",): ["--u", "3", "--duration", "0.1", "--out", "run.csv"],
    ("effects",): [],
    ("signal",): ["sig.csv", "--duration", "0.2", "--rate", "100"],
    ("params",): [],
    ("combine-policies",): ["{A}/p1.npz", "{A}/p2.npz", "--edges", "3", "--out", "comb.npz"],
    ("average-policies",): ["{A}/p1.npz", "{A}/p2.npz", "--out", "avg.npz"],
    ("bifurcation",): ["--out", "bif", "--umax", "1", "--sweep-step", "0"],
    ("compare",): ["{A}/torsional.csv", "--out", "cmp"],
    ("diagnose",): ["{A}/torsional.csv", "--segment", "none"],
    ("identify",): ["{A}/torsional.csv", "--out", "m.json", "--max-nfev", "1", "--segment", "none"],
    ("identify-staged",): ["--upper", "{A}/upper.csv", "--out", "p.json"],
    ("prepare",): [],
    ("evaluate",): ["--config", "torsional", "--controllers", "baseline", "--targets", "1", "--duration", "0.2"]
    + ["--window", "0.1", "--workers", "1", "--out", "ev"],
    ("benchmark",): ["drillgym/Nominal-Motor-v0", "--policy", "baseline", "--duration", "0.5", "--window", "0.2"]
    + ["--targets", "1"],
    ("train",): ["--out", "run", "--timesteps", "1", "--no-progress", "--no-tensorboard"],
    ("rig", "emulate"): ["--port", "tty", "--no-realtime"],
    ("rig", "run"): ["--port", "loop://", "--controller", "const:1", "--duration", "0.1", "--record", "r.csv"]
    + ["--dry-run", "--no-realtime"],
    ("rig", "estop"): ["--port", "loop://", "--attempts", "1", "--timeout-ms", "10"],
    ("rig", "tune"): ["--port", "loop://", "--model-out", "m.json", "--record", "r.csv", "--duration", "0.1"]
    + ["--no-realtime"],
}

#: commands whose valid runs take long (or never end): every case of theirs holds a value to refuse
EXPENSIVE = {
    ("bifurcation",),
    ("compare",),
    ("diagnose",),
    ("identify",),
    ("identify-staged",),
    ("prepare",),
    ("evaluate",),
    ("benchmark",),
    ("train",),
    ("rig", "emulate"),
    ("rig", "run"),
    ("rig", "estop"),
    ("rig", "tune"),
}

#: free text: no value of it is wrong
FREE_TEXT = {"--note"}

#: a valid value of an option given alone to probe its dependencies (else one by its kind)
VALID = {"--observation": "full", "--scenarios": "rest", "--excitation": "10", "--plants": "3"}


def base_argv(cmd: Command, a: Assets) -> list[str]:
    """The base command line of ``cmd``: its entry of :data:`BASES`, or its required parameters filled by kind."""
    if cmd.path in BASES:
        return [*cmd.path, *(w.replace("{A}", str(a.root)) for w in BASES[cmd.path])]
    argv = list(cmd.path)
    for p in cmd.params:
        if p.required:
            value = valid_value(p, a)
            argv += [value] if p.argument else [p.name, value]
    return argv


def valid_value(p: Param, a: Assets) -> str:
    """A value of ``p``'s type the parser takes (what a command does with it is its own)."""
    if p.name in VALID:
        return VALID[p.name]
    return {
        "int": "2",
        "float": "10",
        "str": str(p.default) if isinstance(p.default, str) and p.default else "x",
        "path": ("out_" + p.name.strip("-").lower() + ".json") if p.output else a.params,
    }.get(p.kind, "x")


def must_refuse(p: Param, a: Assets) -> list[str]:
    """Values every command must refuse for ``p`` (whatever the rest of the line)."""
    if p.kind == "int":
        return ["abc", "1.5", "", "nan"]
    if p.kind == "float":
        return ["abc", "", "nan", "inf", "-inf", "1,5"]
    if p.kind == "str":
        return [] if p.name in FREE_TEXT else ["nope!"]
    if p.kind == "path" and p.output:
        bad = [str(Path(a.root) / "notes.txt" / "x.out"), "/proc/drillgym_cannot/x.out"]
        return bad + ([str(a.root) + "/notes.txt"] if p.directory else [])
    if p.kind == "path":
        return [str(a.root) + "/no_such_dir/missing.csv", str(a.root) + "/binary.csv"] + (
            [] if p.directory else [a.adir]
        )
    return []


def may_refuse(p: Param, a: Assets) -> list[str]:
    """Values that are wrong for most (valid for some) commands: the contract holds either way."""
    if p.kind == "int":
        return ["-1", "0", "99999999999999999999", "2147483648"]
    if p.kind == "float":
        return ["-1", "0", "1e308", "-0.0", "1e-300"]
    if p.kind == "str":
        agents = [f"agent:{a.nan_policy}.npz", f"agent:{a.shape_policy}.npz", f"agent:{a.p1}.npz"]
        return ["", " ", ",", "nan", "a,b", *agents]
    if p.kind == "path" and p.output:
        return ["keep.txt", "keep.npz", "sub/dir/new" + (".json" if not p.directory else ""), "", "prev"]
    if p.kind == "path":
        policies = [a.p1 + ".npz", a.nan_policy + ".npz", a.shape_policy + ".npz"]
        hostile = [a.root.as_posix() + f"/models/{n}.json" for n in ("huge_integer", "provenance_types")]
        return [a.empty, a.text, a.garbage_csv, a.garbage_npz, a.broken_json, a.not_params_json, a.torsional, ""] + [
            *policies,
            a.root.as_posix() + "/model.json",
            *hostile,
            a.duplicate_key_yaml,
        ]
    return []


def with_value(argv: list[str], p: Param, value: str | None, n_args: int) -> list[str]:
    """``argv`` with ``p`` set to ``value`` (a flag when None): an option replaced or appended, an argument
    replaced in place (arguments follow the command path)."""
    argv = list(argv)
    if value is None:
        return argv + [p.name]
    if p.argument:
        # the arguments: the words after the command path up to the first option
        start = n_args
        stop = next((i for i in range(start, len(argv)) if argv[i].startswith("--")), len(argv))
        if stop > start:
            argv[start] = value
            return argv
        return argv[:start] + [value] + argv[start:]
    if p.name in argv and not p.multiple:
        i = argv.index(p.name)
        argv[i + 1] = value
        return argv
    return argv + [p.name, value]


# --------------------------------------------------------------------------------------- running and checking


class CaseTimeout(BaseException):
    """A case ran past :data:`CASE_SECONDS` (a BaseException: the command's own handlers let it through)."""


def run(argv: list[str], cwd: Path, seconds: int = CASE_SECONDS) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``drillgym ARGV`` run in this process in ``cwd``, interrupted after
    ``seconds`` (default :data:`CASE_SECONDS`, for cases that must be refused or answered quickly; a command that
    runs the rig's model may first compile its composition, a minute or more on a cold cache)."""
    out, err = io.StringIO(), io.StringIO()
    code: int | str | None = 0
    here = os.getcwd()

    def alarm(signum, frame):  # pragma: no cover - only when a command runs on
        raise CaseTimeout(f"still running after {seconds} s: {' '.join(argv)}")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main([str(w) for w in argv])
            except SystemExit as exc:
                code = exc.code
    except CaseTimeout as exc:
        raise AssertionError(str(exc)) from None
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
        os.chdir(here)
    return (0 if code is None else code), out.getvalue(), err.getvalue()


def snapshot(*roots: Path) -> dict[str, tuple]:
    """Every file (its digest and mtime) and directory under ``roots``."""
    snap: dict[str, tuple] = {}
    for root in roots:
        for p in sorted(Path(root).rglob("*")):
            if p.is_symlink():
                snap[str(p)] = ("link", os.readlink(p))
            elif p.is_dir():
                snap[str(p)] = ("dir",)
            elif p.is_file():
                st = p.stat()
                snap[str(p)] = ("file", hashlib.sha1(p.read_bytes()).hexdigest(), st.st_mtime_ns)
    return snap


def changes(before: dict, after: dict) -> list[str]:
    """Paths created, changed or deleted."""
    return sorted(p for p in set(before) | set(after) if before.get(p) != after.get(p))


def named_outputs(cmd: Command, argv: list[str], cwd: Path) -> list[Path]:
    """The output paths named on the command line (or by an output option's default), resolved from ``cwd``."""
    names = {p.name: p for p in cmd.params if p.output}
    out: list[Path] = []
    for i, w in enumerate(argv[:-1]):
        if w in names:
            out.append(cwd / argv[i + 1])
    for p in cmd.params:
        if p.output and p.argument:  # an output argument (signal OUT): the first word after the path
            k = len(cmd.path)
            if k < len(argv):
                out.append(cwd / argv[k])
        if p.output and not p.argument and p.name not in argv and isinstance(p.default, (str, Path)) and p.default:
            out.append(cwd / str(p.default))
    return [Path(os.path.normpath(o)) for o in out]


def outside(changed: list[str], outputs: list[Path]) -> list[str]:
    """The changed paths that are neither a named output, under one, nor one's numbered sibling (rec_001.csv)."""
    bad = []
    for c in changed:
        cp = Path(c)
        ok = False
        for o in outputs:
            if cp == o or o in cp.parents or (cp.parent == o.parent and cp.name.startswith(o.stem)):
                ok = True
            elif cp in o.parents:  # a missing directory created for it
                ok = True
        if not ok:
            bad.append(c)
    return bad


def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"non-finite JSON literal {name}")

    return json.loads(text, parse_constant=refuse)


def check_output_file(path: Path) -> None:
    """A written file reads back, by its content: a PNG, an .npz of finite arrays, strict JSON, YAML, a CSV of
    finite numbers, UTF-8 text."""
    suffix = path.suffix.lower()
    data = path.read_bytes()
    if data.startswith(b"\x89PNG"):
        return
    if data.startswith(b"PK"):
        suffix = ".npz"
    elif data.lstrip()[:1] in (b"{", b"["):
        _strict_json(data.decode("utf-8"))
        return
    if suffix in (".yaml", ".yml"):
        import yaml

        yaml.safe_load(data.decode("utf-8"))
    elif suffix != ".npz" and b"," in data:
        for line in data.decode("utf-8").splitlines():
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            for cell in line.split(","):
                try:
                    v = float(cell)
                except ValueError:
                    continue  # a header or a text column
                assert math.isfinite(v), f"{path}: non-finite value in {line!r}"
    elif suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            for k in z.files:
                v = z[k]
                if v.dtype.kind in "fc":
                    assert np.isfinite(v).all(), f"{path}: non-finite values in {k}"
    elif suffix == ".png":
        raise AssertionError(f"{path}: not a PNG")
    else:
        data.decode("utf-8")


def check_contract(cmd: Command, argv: list[str], work: Path, a: Assets, names: tuple[str, ...]) -> str:
    """Run ``argv`` in ``work`` and assert the contract; returns ``"refused"`` or ``"ran"``.

    ``names``: what a refusal may name (the options and values the case changed)."""
    before = snapshot(work, Path(a.root))
    code, out, err = run(argv, work)
    after = snapshot(work, Path(a.root))
    changed = changes(before, after)
    line = err.strip().split("\r")[-1].strip()  # a progress bar cleared by carriage returns is not a line
    assert "Traceback" not in err and "internal error" not in err, f"{argv}: a traceback\n{err[-3000:]}"
    assert code in (0, USER_ERROR), f"{argv}: exit {code}\n{err[-2000:]}"
    if code == USER_ERROR:
        assert line and "\n" not in err.strip(), f"{argv}: the refusal is not one line:\n{err}"
        assert line.startswith("drillgym: error: "), f"{argv}: {line}"
        assert not changed, f"{argv}: refused ({line}) after changing {changed}"
        if names:
            low = line.lower()
            assert any(n.lower() in low for n in names if n), f"{argv}: names none of {names}: {line}"
        return "refused"
    outputs = named_outputs(cmd, argv, work)
    stray = outside(changed, outputs)
    assert not stray, f"{argv}: changed files not named on the command line: {stray}"
    for c in changed:
        p = Path(c)
        if p.is_file():
            check_output_file(p)
    if "--json" in argv and cmd.path not in (("benchmark",),) and out.strip():
        _strict_json(out)
    return "ran"


def fresh_work(root: Path) -> Path:
    """A new scratch directory (the case's cwd) with files of the user's in it."""
    work = Path(tempfile.mkdtemp(prefix="case-", dir=root))
    (work / "keep.npz").write_bytes(b"the user's own npz\n")
    (work / "keep.txt").write_text("the user's own notes\n")
    (work / "prev").mkdir()  # an earlier run's directory
    (work / "prev" / "config.yml").write_text("env_id: an earlier run\n")
    (work / "prev" / "results.csv").write_text("t,u\n0,1\n")
    return work
