"""The README as written: every Python snippet runs (in a fresh directory), every `drillgym ...`
command it shows uses a subcommand and options that exist, and the ten-minute tour's shell steps
run in order in a fresh directory (each file a step reads is written by an earlier step)."""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from drillgym.cli import app

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]), "MPLBACKEND": "Agg"}


def fenced_blocks(text: str) -> list[tuple[str, str]]:
    """Every fenced code block of a Markdown text as (language, body), in order."""
    blocks, lang, body = [], None, []
    for line in text.splitlines():
        stripped = line.strip()
        if lang is None and stripped.startswith("```"):
            lang, body = stripped[3:].strip(), []
        elif lang is not None and stripped == "```":
            blocks.append((lang, "\n".join(body) + "\n"))
            lang = None
        elif lang is not None:
            body.append(line)
    return blocks


SNIPPETS = [body for lang, body in fenced_blocks(README) if lang == "python"]


def _section(text: str, title: str) -> str:
    start = text.index(f"\n## {title}")
    end = text.find("\n## ", start + 1)
    return text[start : end if end > 0 else len(text)]


TOUR = _section(README, "A ten-minute tour")


def shell_commands(text: str) -> list[str]:
    """Every `drillgym ...` command of the ```sh blocks (continuations joined, comments dropped), in order."""
    cmds = []
    for lang, body in fenced_blocks(text):
        if lang not in ("sh", "bash", "console", ""):
            continue
        for line in body.replace("\\\n", " ").splitlines():
            c = line.strip().lstrip("$").strip().split("#")[0].rstrip(" &").strip()
            if c.startswith("drillgym ") and not c.startswith("drillgym/"):
                cmds.extend(part.strip() for part in c.split(" / ") if part.strip().startswith("drillgym "))
    return cmds


def _commands() -> list[str]:
    """Every `drillgym ...` command of the README: lines of code blocks and backticked spans."""
    found = shell_commands(README)
    for span in re.findall(r"`(drillgym [^`]+)`", README):
        found.extend(part.strip() for part in span.split(" / ") if part.strip().startswith("drillgym "))
    return found


def test_readme_has_snippets():
    assert len(SNIPPETS) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_python_snippet_runs_as_written(tmp_path, index):
    shutil.copytree(ROOT / "examples", tmp_path / "examples")  # the user effect files the README uses
    res = subprocess.run(
        [sys.executable, "-c", SNIPPETS[index]], cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=600
    )
    assert res.returncode == 0, f"README python snippet {index}:\n{SNIPPETS[index]}\n{res.stderr[-2000:]}"


_HELP: dict[str, str] = {}


def _help(sub: tuple[str, ...]) -> str:
    key = " ".join(sub)
    if key not in _HELP:
        res = CliRunner().invoke(app, [*sub, "--help"], terminal_width=250)
        assert res.exit_code == 0, f"`drillgym {key}` does not exist: {res.output}"
        _HELP[key] = res.output
    return _HELP[key]


def check_command(cmd: str, where: str = "README") -> None:
    """The subcommand of `cmd` exists and takes every option `cmd` shows."""
    words = cmd.split()
    sub = tuple(words[1:3]) if words[1] == "rig" else (words[1],)
    help_text = _help(sub)
    for opt in set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", cmd)):
        assert re.search(rf"{re.escape(opt)}\b", help_text), (
            f"{where}: `{cmd}`: {opt} is not an option of `drillgym {' '.join(sub)}`"
        )


def test_readme_commands_exist_with_their_options():
    cmds = _commands()
    assert len(cmds) >= 20
    for cmd in cmds:
        check_command(cmd)


def test_tour_goes_from_simulation_to_a_falling_error():
    """The tour's stages in order: simulate -> env -> evaluate -> diagnose a recording -> add an effect ->
    identify (the Python steps run in test_python_snippet_runs_as_written)."""
    cmds = shell_commands(TOUR)
    subs = [c.split()[1] for c in cmds]
    order = ["simulate", "evaluate", "simulate", "diagnose", "identify"]
    pos = 0
    for sub in subs:
        if pos < len(order) and sub == order[pos]:
            pos += 1
    assert pos == len(order), f"the tour's shell steps {subs} do not follow {order}"
    assert any("--add-effect" in c for c in cmds if c.split()[1] == "simulate"), "no recording with a hidden effect"
    assert any("--add-effect" in c for c in cmds if c.split()[1] == "identify"), "no identify with the effect added"
    assert "gym.make" in "".join(body for lang, body in fenced_blocks(TOUR) if lang == "python")


def _files_read_and_written(cmd: str) -> tuple[list[str], list[str]]:
    words = shlex.split(cmd)[1:]
    sub = words[0]
    written, read, positional = [], [], []
    i = 1
    while i < len(words):
        w = words[i]
        if w.startswith("--"):
            value = words[i + 1] if i + 1 < len(words) and not words[i + 1].startswith("--") else None
            if w in ("--out", "--plot", "--record", "--candidate-out") and value:
                written.append(value)
            elif w in ("--params", "--input", "--uncertainty") and value:
                read.append(value)
            i += 2 if value is not None else 1
            continue
        positional.append(w)
        i += 1
    if sub in ("compare", "diagnose", "identify"):
        read.extend(positional[:1])
    return read, written


def test_tour_shell_steps_read_only_what_earlier_steps_wrote():
    """Run in a fresh directory, each step finds its input files: an earlier step of the tour wrote them."""
    written: set[str] = set()
    for cmd in shell_commands(TOUR):
        check_command(cmd, "README tour")
        read, out = _files_read_and_written(cmd)
        for f in read:
            assert f in written, f"README tour: `{cmd}` reads {f}, which no earlier step writes"
        written.update(out)


@pytest.mark.slow
def test_tour_first_step_runs_as_written(tmp_path):
    """The tour's first shell step in a fresh directory (the long steps are checked by their options)."""
    cmd = shell_commands(TOUR)[0]
    res = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *shlex.split(cmd)[1:]],
        cwd=tmp_path,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    for f in _files_read_and_written(cmd)[1]:
        assert (tmp_path / f).exists(), f


def test_make_demo_command_runs(tmp_path):
    """The one command `make demo` runs, as the Makefile writes it."""
    line = next(ln for ln in (ROOT / "Makefile").read_text().splitlines() if "drillgym simulate" in ln)
    args = line.split("drillgym", 1)[1].split()
    res = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args],
        cwd=tmp_path,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "out" / "demo.csv").exists() and (tmp_path / "out" / "demo.png").exists()
