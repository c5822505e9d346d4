"""Bad inputs for every command and public function: Hypothesis strategies and the checks a case must pass.

A *case* is a command line (or a call) with one bad value in it. It passes when it is refused in one
line ``drillgym: error: ...`` (exit 2) naming the option or argument, or when it gives a documented
valid result that is right; and in both cases no file that existed before is changed or deleted.

The assets (recordings, garbage files, a directory, an effect file that exits) are built once in a
directory shared by the cases; each case writes into a fresh work directory holding a decoy file.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from drillgym.cli import main

#: what a user error exits with
USER_ERROR = 2

#: a float of magnitude beyond any physical quantity of the rig
HUGE = "1e300"


# --------------------------------------------------------------------------------------- the assets


@dataclass(frozen=True)
class Assets:
    """Files every case may name as input (never to be changed by a case)."""

    root: Path

    def __getattr__(self, name: str) -> str:  # assets.torsional -> str path of torsional.csv etc.
        names = {
            "torsional": "torsional.csv",
            "upper": "upper.csv",
            "lateral": "lateral.csv",
            "signal": "signal.csv",
            "params": "params.json",
            "garbage_csv": "garbage.csv",
            "garbage_npz": "garbage.npz",
            "not_params_json": "not_params.json",
            "broken_json": "broken.json",
            "empty": "empty.csv",
            "binary": "binary.csv",
            "adir": "adir",
            "exiting_effect": "exiting_effect.py",
            "raising_effect": "raising_effect.py",
            "text": "notes.txt",
            "policy_zip": "model.zip",
            "duplicate_key_yaml": "duplicate_key.yaml",
        }
        if name in names:
            return str(self.root / names[name])
        raise AttributeError(name)

    @property
    def missing(self) -> str:
        return str(self.root / "no_such_dir" / "missing.csv")

    @property
    def under_file(self) -> str:
        """A path whose parent is an existing file: cannot be created."""
        return str(self.root / "notes.txt" / "out.csv")


def build_assets(root: Path) -> Assets:
    """Recordings of 0.2 s (torsional, upper, lateral), an input signal, a partial parameter file and
    the garbage: a csv that is not a time series, an npz that is not a policy, JSON that is not a
    parameter file, invalid JSON, an empty and a binary file, a directory, effect files that exit or raise."""
    root.mkdir(parents=True, exist_ok=True)
    a = Assets(root)
    for cfg, u in (("torsional", "3"), ("upper", "2"), ("lateral", "3")):
        code, _, err = run_cli("simulate", "--config", cfg, "--u", u, "--duration", "0.2", "--out", getattr(a, cfg))
        assert code == 0, err
    code, _, err = run_cli("signal", a.signal, "--duration", "0.2", "--rate", "100")
    assert code == 0, err
    (root / "params.json").write_text('{"Jl": 0.035}\n')
    (root / "garbage.csv").write_text("hello,world\n1,2\nthree,four\n")
    np.savez(root / "garbage.npz", something=np.arange(3))
    (root / "not_params.json").write_text('{"who": "not a parameter file", "list": [1, 2]}\n')
    (root / "broken.json").write_text('{"Jl": 0.035,,,')
    (root / "empty.csv").write_text("")
    (root / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (root / "adir").mkdir(exist_ok=True)
    (root / "adir" / "inside.txt").write_text("keep me\n")
    (root / "notes.txt").write_text("a file of the user's\n")
    (root / "model.zip").write_bytes(b"PK\x03\x04 not really a zip")
    (root / "exiting_effect.py").write_text("import sys\nsys.exit(3)\n")
    (root / "raising_effect.py").write_text("raise RuntimeError('broken at import')\n")
    (root / "duplicate_key.yaml").write_text("Jl: 0.04\nJl: 0.05\n")  # a mapping that gives one key twice
    return a


# --------------------------------------------------------------------------------------- model files


#: a valid model file (one library effect): each hostile model file is it with one thing wrong
GOOD_MODEL = {
    "format": "drillgym-model",
    "version": 2,
    "params": {"Jl": 0.04},
    "effects": [{"name": "motor_lag", "kind": "input", "spec": "motor_lag", "values": {"tau_m": 0.03}}],
    "provenance": {"route": "user", "recording": None, "recording_sha256": None, "settings": {}, "version": ""},
}


def _edited(edit: Callable[[dict], None]) -> dict:
    import copy

    data = copy.deepcopy(GOOD_MODEL)
    edit(data)
    return data


#: hostile model files (name -> text, or a change of :data:`GOOD_MODEL`): each must be refused in one line
#: naming the file, by every reader of a model file (``Model.load``, ``--model``, ``--params`` of diagnose); a
#: key given twice is refused, not read as its last value
HOSTILE_MODELS: dict[str, str | Callable[[dict], None]] = {
    "huge_integer": '{"params": {"Jl": 1' + "0" * 400 + "}}",
    "huge_integer_value": '{"effects": [{"spec": "motor_lag", "values": {"tau_m": 1' + "0" * 400 + "}}]}",
    "huge_integer_std": '{"params": {}, "std": {"Jl": 1' + "0" * 400 + "}}",
    "duplicate_key": '{"params": {"Jl": 0.04, "Jl": 0.05}}',
    "duplicate_key.yaml": "params:\n  Jl: 0.04\n  Jl: 0.05\n",
    "duplicate_effect_key.yaml": "effects:\n  - spec: motor_lag\n    values: {tau_m: 0.03, tau_m: 0.04}\n",
    "provenance_types": lambda d: d.update(provenance={"route": 3, "settings": [1]}),
    "provenance_settings_list": lambda d: d["provenance"].update(settings=[["a", 1, 2]]),
    "later_version": lambda d: d.update(version=99),
    "version_text": lambda d: d.update(version="two"),
    "unknown_std_name": lambda d: d.update(std={"not_a_parameter": 1.0}),
    "unknown_record_key": lambda d: d["effects"][0].update(colour="red"),
    "record_name_not_its_effect": lambda d: d["effects"][0].update(name="input_delay"),
    "record_kind_not_its_effect": lambda d: d["effects"][0].update(kind="force"),
    "value_filed_under_another_effect": lambda d: d["effects"].append(
        {"spec": "input_delay", "values": {"tau_m": 0.01}}
    ),
    "std_filed_under_another_effect": lambda d: d["effects"][0].update(std={"delay": 0.001}),
}


def build_hostile_models(root: Path) -> dict[str, str]:
    """Write :data:`HOSTILE_MODELS` under ``root/models/`` (NAME.json, or NAME as given when it has a suffix);
    returns name -> path."""
    import json

    folder = root / "models"
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for name, what in HOSTILE_MODELS.items():
        text = what if isinstance(what, str) else json.dumps(_edited(what))
        file = folder / (name if "." in name else f"{name}.json")
        file.write_text(text)
        out[name] = str(file)
    return out


# --------------------------------------------------------------------------------------- running


def run_cli(*argv: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``drillgym ARGV`` run in this process."""
    out, err = io.StringIO(), io.StringIO()
    code: int | str | None = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return (0 if code is None else code), out.getvalue(), err.getvalue()


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` with its bytes."""
    return {str(p): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file() and not p.is_symlink()}


def assert_nothing_lost(before: dict[str, bytes], after: dict[str, bytes], may_replace: tuple[str, ...] = ()) -> None:
    """No file of ``before`` changed or deleted, except those the case asked to replace."""
    lost = [p for p in before if p not in after]
    changed = [p for p in before if p in after and after[p] != before[p] and p not in may_replace]
    assert not lost and not changed, f"deleted: {lost}; changed: {changed}"


def assert_refused(code: int, err: str, *names: str) -> str:
    """One line ``drillgym: error: ...`` on stderr, exit 2, naming one of ``names``; returns the line."""
    assert code == USER_ERROR, f"exit {code}, stderr:\n{err}"
    assert "Traceback" not in err and "internal error" not in err, err
    line = err.strip()
    assert line and "\n" not in line, f"not one line:\n{err}"
    assert line.startswith("drillgym: error: ") or line.startswith("drillgym ") and ": error: " in line, line
    if names:
        assert any(n in line for n in names), f"names none of {names}: {line}"
    return line


@dataclass
class Case:
    """One command line with a bad value.

    ``names``: what the error must name (the option, or the value for an argument); ``valid``: when the
    value is documented as valid, a check of the result (work dir, stdout) that must hold if the command
    succeeds; ``may_replace``: files the command may rewrite.
    """

    argv: list[str]
    names: tuple[str, ...]
    valid: Callable[[Path, str], None] | None = None
    may_replace: tuple[str, ...] = ()
    note: str = ""
    extra: dict = field(default_factory=dict)


#: failing cases whose fix lies with another part of the project, reported there: (words all in the
#: command line, why). A matching failure is tolerated (returned as 'known'), a passing case is fine.
KNOWN_ELSEWHERE = [
    (("rig", "run", "--controller"), "rig run's controller refusal does not name --controller yet"),
]


def _known(argv: list[str]) -> str | None:
    line = " ".join(argv)
    for words, why in KNOWN_ELSEWHERE:
        if all(w in line for w in words):
            return why
    return None


def check_case(case: Case, root: Path) -> str:
    """Run ``case`` and assert it is refused in one line (or gives its documented valid result), with
    nothing lost under ``root``. Returns 'refused' or 'valid'.

    With the environment variable ``BAD_INPUTS_LOG`` set to a file, a failing case is appended to that
    file (argv, seconds, what failed) instead of failing the test: a survey of every case in one run.
    """
    log = os.environ.get("BAD_INPUTS_LOG")
    start = time.process_time()
    try:
        before = snapshot(root)
        code, out, err = run_cli(*case.argv)
        assert_nothing_lost(before, snapshot(root), case.may_replace)
        if code == 0 and case.valid is not None:
            case.valid(root, out)
            return "valid"
        assert_refused(code, err, *case.names)
        return "refused"
    except AssertionError as exc:
        if _known(case.argv) and not log:
            return "known"
        if not log:
            raise
        with open(log, "a", encoding="utf-8") as fh:
            what = str(exc)
            what = " | ".join(what.strip().splitlines()[-2:]) if "Traceback" in what else " ".join(what.split())
            what = what[:500]
            fh.write(f"{time.process_time() - start:6.2f}s {' '.join(case.argv)!r} {case.names!r}: {what}\n")
        return "failed"


def fresh_dir(root: Path) -> Path:
    """A new work directory under ``root`` with a decoy file of the user's in it."""
    work = Path(tempfile.mkdtemp(prefix="case-", dir=root))
    (work / "keep.npz").write_bytes(b"the user's own npz\n")
    (work / "keep.txt").write_text("the user's own notes\n")
    return work


# --------------------------------------------------------------------------------------- values


def _floats_below(hi: float) -> st.SearchStrategy[str]:
    return st.floats(max_value=hi, allow_nan=False, allow_infinity=False, exclude_max=True).map(repr)


NOT_A_NUMBER = st.sampled_from(["abc", "", " ", "1,5", "0x10", "one", "--", "1e", "nan%"])
NON_FINITE = st.sampled_from(["nan", "inf", "-inf", "NaN", "1e400", "-1e400"])
NOT_AN_INT = st.sampled_from(["abc", "", "1.5", "2e3", "nan", "inf", "0x10"])


def positive_float_bad() -> st.SearchStrategy[str]:
    """Values a positive finite number option must refuse."""
    return st.one_of(NOT_A_NUMBER, NON_FINITE, st.just("0"), st.just("-0.0"), _floats_below(0.0))


def finite_float_bad() -> st.SearchStrategy[str]:
    """Values a finite number option must refuse."""
    return st.one_of(NOT_A_NUMBER, NON_FINITE)


def positive_int_bad() -> st.SearchStrategy[str]:
    """Values an integer >= 1 option must refuse."""
    return st.one_of(NOT_AN_INT, st.just("0"), st.integers(max_value=-1).map(str))


def nonneg_int_bad() -> st.SearchStrategy[str]:
    """Values an integer >= 0 option must refuse."""
    return st.one_of(NOT_AN_INT, st.integers(max_value=-1).map(str))


def choice_bad(valid: list[str]) -> st.SearchStrategy[str]:
    """Words that are none of ``valid``."""
    low = {v.lower() for v in valid}
    words = st.text(alphabet="abcdefghijklmnopqrstuvwxyz_-+", min_size=1, max_size=10)
    return st.one_of(st.sampled_from(["", " ", "nope", "42", "torsional,", "*"]), words).filter(
        lambda w: w.strip().lower() not in low
    )


def input_file_bad(a: Assets, *, kinds: tuple[str, ...] = ("missing", "dir", "garbage_csv", "empty", "binary")):
    """Paths an input-file option must refuse: missing, a directory, files of the wrong content."""
    table = {
        "missing": a.missing,
        "dir": a.adir,
        "empty_path": "",
        "garbage_csv": a.garbage_csv,
        "garbage_npz": a.garbage_npz,
        "not_params_json": a.not_params_json,
        "broken_json": a.broken_json,
        "empty": a.empty,
        "binary": a.binary,
        "text": a.text,
        "proc": "/proc/self/nonexistent.csv",
        "duplicate_key_yaml": a.duplicate_key_yaml,
    }
    return st.sampled_from([table[k] for k in kinds])


def output_file_bad(a: Assets, work: Path, suffix: str = ".csv") -> list[str]:
    """Paths an output-file option must refuse: a directory, under a file, unwritable, the user's files."""
    return [
        a.adir,
        str(work),
        a.under_file,
        f"/proc/drillgym_cannot{suffix}",
        f"/proc/self/nope/x{suffix}",
        str(work / "keep.npz"),
        str(work / "keep.txt"),
        a.torsional if suffix != ".csv" else a.garbage_npz,
        "/dev/null",
    ]


def output_dir_bad(a: Assets, work: Path) -> list[str]:
    """Paths an output-directory option must refuse: a file, under a file, unwritable."""
    return [a.text, str(work / "keep.npz"), a.under_file, "/proc/drillgym_cannot", "/dev/null"]


def finite_file(path: Path) -> None:
    """A time-series file that reads back with finite values."""
    from drillgym.io import read_timeseries

    ts = read_timeseries(path)
    for name in ("t", "u", "theta_u"):
        v = np.asarray(getattr(ts, name))
        assert v.size and np.isfinite(v).all(), (path, name)


def is_finite_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
