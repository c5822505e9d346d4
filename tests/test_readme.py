"""The README as written: every Python snippet runs (in a fresh directory), and every `drillgym ...`
command it shows uses a subcommand and options that exist."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from drillgym.cli import app

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
SNIPPETS = re.findall(r"```python\n(.*?)```", README, flags=re.S)
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
       "MPLBACKEND": "Agg"}


def test_readme_has_snippets():
    assert len(SNIPPETS) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_python_snippet_runs_as_written(tmp_path, index):
    shutil.copytree(ROOT / "examples", tmp_path / "examples")  # the user effect files the README uses
    res = subprocess.run([sys.executable, "-c", SNIPPETS[index]], cwd=tmp_path, env=ENV, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, f"README python snippet {index}:\n{SNIPPETS[index]}\n{res.stderr[-2000:]}"


def _commands() -> list[str]:
    """Every `drillgym ...` command of the README: lines of code blocks and backticked spans (continuations joined)."""
    blocks = re.findall(r"```(?:sh)?\n(.*?)```", README, flags=re.S)
    text = "\n".join(blocks).replace("\\\n", " ")
    found = [ln.strip().lstrip("$").strip() for ln in text.splitlines()]
    found += re.findall(r"`(drillgym [^`]+)`", README)
    cmds = []
    for c in found:
        c = c.split("#")[0].rstrip(" &")
        if c.startswith("drillgym ") and not c.startswith("drillgym/"):
            cmds.extend(part.strip() for part in c.split(" / ") if part.strip().startswith("drillgym "))
    return cmds


_HELP: dict[str, str] = {}


def _help(sub: tuple[str, ...]) -> str:
    key = " ".join(sub)
    if key not in _HELP:
        res = CliRunner().invoke(app, [*sub, "--help"], terminal_width=250)
        assert res.exit_code == 0, f"`drillgym {key}` does not exist: {res.output}"
        _HELP[key] = res.output
    return _HELP[key]


def test_readme_commands_exist_with_their_options():
    cmds = _commands()
    assert len(cmds) >= 20
    for cmd in cmds:
        words = cmd.split()
        sub = tuple(words[1:3]) if words[1] == "rig" else (words[1],)
        help_text = _help(sub)
        for opt in set(re.findall(r"(--[a-z][a-z0-9-]*)", cmd)):
            assert re.search(rf"{re.escape(opt)}\b", help_text), f"README: `{cmd}`: {opt} is not an option of " \
                                                                 f"`drillgym {' '.join(sub)}`"


def test_make_demo_command_runs(tmp_path):
    """The one command `make demo` runs, as the Makefile writes it."""
    line = next(ln for ln in (ROOT / "Makefile").read_text().splitlines() if "drillgym simulate" in ln)
    args = line.split("drillgym", 1)[1].split()
    res = subprocess.run([sys.executable, "-m", "drillgym.cli", *args], cwd=tmp_path, env=ENV, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "out" / "demo.csv").exists() and (tmp_path / "out" / "demo.png").exists()
