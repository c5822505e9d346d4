"""The command line answers without loading the numerics: behaviour, not timing.

``drillgym --help``, the ``--help`` of every command and subcommand, and the refusal of a bad option
run in a fresh interpreter and must not import numba, scipy, torch, Gymnasium (nor the other heavy
stacks below); ``import drillgym`` alone neither. The Gymnasium ids are still registered for a user
who imports drillgym and Gymnasium, in either order. The timings are measured by
``benchmarks/bench_cli.py`` (docs/benchmarks.md).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

#: top-level packages a help or a refusal must not load (numba also loads LLVM, 110 MB; numpy and pydantic,
#: which typer uses to check values, each take about a quarter of the time a help may take)
HEAVY = (
    "numpy",
    "numba",
    "llvmlite",
    "scipy",
    "torch",
    "gymnasium",
    "matplotlib",
    "control",
    "pandas",
    "stable_baselines3",
    "pydantic",
)

#: prints the heavy packages loaded so far as one JSON line, after the code before it
_REPORT = f"""
import json as _json, sys as _sys
print("LOADED=" + _json.dumps(sorted({{m.split(".")[0] for m in _sys.modules}} & set({HEAVY!r}))))
"""

#: runs every command's --help (the root's, groups', subcommands') in one interpreter, then reports
_ALL_HELPS = """
import contextlib, io, json, sys
import typer.main
from drillgym.cli import app, main

def paths(cmd, prefix):
    yield prefix
    for name, sub in sorted(getattr(cmd, "commands", {}).items()):
        yield from paths(sub, prefix + [name])

codes = {}
for path in paths(typer.main.get_command(app), []):
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            main(path + ["--help"])
        except SystemExit as exc:
            codes[" ".join(path)] = (exc.code, "Usage:" in out.getvalue())
print("HELPS=" + json.dumps(codes))
"""


def _python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)


def _line(stdout: str, key: str):
    return json.loads(next(line for line in stdout.splitlines() if line.startswith(key + "="))[len(key) + 1 :])


def test_every_help_loads_no_heavy_package():
    p = _python(_ALL_HELPS + _REPORT)
    assert p.returncode == 0, p.stderr[-2000:]
    helps = _line(p.stdout, "HELPS")
    # the root, the core's commands and those of controllers, agents and hw (entry points), rig's subcommands
    for command in ("", "simulate", "bifurcation", "diagnose", "params", "evaluate", "train", "rig", "rig run"):
        assert command in helps, sorted(helps)
    assert {c: v for c, v in helps.items() if v != [0, True]} == {}  # each printed its usage, exit 0
    assert _line(p.stdout, "LOADED") == []
    assert "warning" not in p.stderr  # no command provider failed to load


@pytest.mark.parametrize("args", [["simulate"], ["evaluate"], ["train"], ["rig", "run"], []])
def test_a_bad_option_is_refused_in_one_line_without_loading_the_numerics(args):
    code = (
        "import sys\nfrom drillgym.cli import main\n"
        f"try:\n    main({args + ['--no-such-option']!r})\n"
        "except SystemExit as exc:\n    print('CODE=' + str(exc.code))\n" + _REPORT
    )
    p = _python(code)
    assert _line(p.stdout, "CODE") == 2, p.stderr[-2000:]
    assert _line(p.stdout, "LOADED") == []
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("drillgym: error: ") and "--no-such-option" in lines[0], p.stderr


def test_the_console_script_refuses_a_bad_option_with_exit_code_2():
    script = Path(sys.executable).with_name("drillgym")
    if not script.exists():
        pytest.skip("the drillgym console script is not installed beside this interpreter")
    p = subprocess.run([str(script), "simulate", "--no-such-option"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.strip() == "drillgym: error: No such option: --no-such-option (see 'drillgym simulate --help')"


def test_import_drillgym_alone_loads_no_heavy_package():
    p = _python(
        "import drillgym" + _REPORT + "print('ALL=' + _json.dumps(sorted(set(drillgym.__all__) - set(dir(drillgym)))))"
    )
    assert p.returncode == 0, p.stderr[-2000:]
    assert _line(p.stdout, "LOADED") == []
    assert _line(p.stdout, "ALL") == []  # every public name is listed by dir() before it loads


def test_the_public_names_still_import_from_the_package():
    code = (
        "import drillgym\nfrom drillgym import simulate, RigParams, Trajectory, DEFAULT_DT, parse_configuration\n"
        "assert callable(simulate) and RigParams().to_dict() and DEFAULT_DT > 0\n"
        "missing = [n for n in drillgym.__all__ if not hasattr(drillgym, n)]\n"
        "assert not missing, missing\n"
        "assert drillgym.simulate is simulate and drillgym.params.RigParams is RigParams\n"
        "try:\n    drillgym.no_such_name\nexcept AttributeError as exc:\n    print('ERR=' + repr(str(exc)))\n"
    )
    p = _python(code)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "no_such_name" in p.stdout


@pytest.mark.slow
def test_gym_make_works_after_import_drillgym_then_gymnasium():
    code = (
        "import drillgym\nimport gymnasium as gym\n"
        "env = gym.make('drillgym/Torsional-v0')\nobs, info = env.reset(seed=0)\n"
        "print('ID=' + env.spec.id, len(obs))\n"
    )
    p = _python(code)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "ID=drillgym/Torsional-v0" in p.stdout


def test_the_vector_width_is_set_when_numba_loads():
    """``import drillgym`` no longer loads LLVM to set numba's CPU features: they are set just before numba
    loads, as they were at ``import drillgym`` (the host's features at full width on AVX-512 hosts)."""
    code = (
        "import os, sys\nimport drillgym\nassert 'llvmlite' not in sys.modules\nimport numba\n"
        "import llvmlite.binding as ll\nfrom drillgym._simd import full_width_features\n"
        "ll.initialize_native_target()\n"
        "assert os.environ.get('NUMBA_CPU_FEATURES') == full_width_features(ll.get_host_cpu_features().flatten())\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("DRILLGYM_SIMD", "NUMBA_CPU_FEATURES", "NUMBA_CPU_NAME")}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert p.returncode == 0, p.stderr[-2000:]


def test_the_ids_are_registered_when_gymnasium_was_imported_first():
    code = (
        "import gymnasium as gym\nimport drillgym\n"
        "ids = ['drillgym/Torsional-v0', 'drillgym/Lateral-v0', 'drillgym/Coupled-v0', 'drillgym/Hardware-v0']\n"
        "print('MISSING=' + __import__('json').dumps([i for i in ids if i not in gym.registry]))"
    )
    p = _python(code)
    assert p.returncode == 0, p.stderr[-2000:]
    assert _line(p.stdout, "MISSING") == []
