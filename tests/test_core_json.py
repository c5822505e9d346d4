"""Every JSON drillgym writes is strict JSON: no NaN/Infinity literal, no silent null.

The writer (``drillgym.io.write_json`` / ``dumps_json``) turns a non-finite number into null only
with a ``warnings`` entry naming it, or refuses it; the commands that write or print JSON are run on
tiny inputs (a compare whose R² is undefined among them) and every JSON they produce is parsed with a
parser that refuses NaN, Infinity and -Infinity.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from drillgym.errors import OutputPathError
from drillgym.io import dumps_json, loads_strict, write_json


def test_non_finite_numbers_are_null_with_a_warning_or_refused() -> None:
    text = dumps_json({"r2": np.float64("nan"), "v": [np.float32(1.5), float("-inf")], "n": np.int64(3)})
    data = loads_strict(text)
    assert data["r2"] is None and data["v"] == [1.5, None] and data["n"] == 3
    assert data["warnings"] == [
        "r2: not a finite number (nan), written as null",
        "v[1]: not a finite number (-inf), written as null",
    ]
    with pytest.raises(ValueError, match=r"r2 is not a finite number \(nan\)"):
        dumps_json({"r2": float("nan")}, nonfinite="refuse")
    with pytest.raises(ValueError, match="cannot carry a warning"):
        dumps_json([float("nan")])
    with pytest.raises(ValueError, match="Infinity is not JSON"):
        loads_strict('{"a": Infinity}')


def test_write_json_replaces_whole_or_not_at_all(tmp_path: Path) -> None:
    path = tmp_path / "out.json"
    path.write_text('{"old": 1}\n', encoding="utf-8")
    with pytest.raises(TypeError, match="object has no JSON form"):
        write_json(path, {"x": object()})
    assert path.read_text(encoding="utf-8") == '{"old": 1}\n'  # untouched
    write_json(path, {"new": np.arange(2)})
    assert loads_strict(path.read_text(encoding="utf-8")) == {"new": [0, 1]}
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]  # no temporary file left
    with pytest.raises(OutputPathError, match="is a directory"):
        write_json(tmp_path, {})


def _cli(*args: str, cwd: Path) -> str:
    res = subprocess.run(
        [sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=600, cwd=cwd
    )
    assert res.returncode == 0, res.stderr
    return res.stdout


def _meta(csv: Path) -> dict:
    line = csv.read_text(encoding="utf-8").splitlines()[0]
    assert line.startswith("# meta: ")
    return loads_strict(line[len("# meta: ") :])


def _constant_upper(path: Path) -> Path:
    """An upper-part recording that never moves: R² of theta_u is undefined (no variance)."""
    rows = "".join(f"{k * 0.004!r},0.0,0.0\n" for k in range(750))
    path.write_text('# meta: {"configuration": "upper"}\nt,u,theta_u\n' + rows, encoding="utf-8")
    return path


@pytest.mark.slow
def test_every_command_writes_strict_json(tmp_path: Path) -> None:
    _cli("params", "--out", "p.json", cwd=tmp_path)
    assert "km" in loads_strict((tmp_path / "p.json").read_text(encoding="utf-8"))["params"]
    assert isinstance(loads_strict(_cli("effects", "--json", cwd=tmp_path)), list)
    _cli("signal", "s.csv", "--duration", "2", "--rate", "100", cwd=tmp_path)
    assert _meta(tmp_path / "s.csv")["source"] == "signal"
    _cli("simulate", "--config", "upper", "--u", "2", "--duration", "3", "--out", "up.csv", cwd=tmp_path)
    assert _meta(tmp_path / "up.csv")["configuration"] == "upper"

    _cli("compare", str(_constant_upper(tmp_path / "still.csv")), "--out", "cmp", "--segment", "none", cwd=tmp_path)
    comp = loads_strict((tmp_path / "cmp" / "compare.json").read_text(encoding="utf-8"))
    assert comp["metrics"]["theta_u"]["r2"] is None
    assert any(
        w.startswith("metrics.theta_u.r2: not computed because the measured theta_u is constant")
        for w in comp["warnings"]
    )

    printed = loads_strict(_cli("identify", "up.csv", "--out", "m.json", "--json", "--max-nfev", "2", cwd=tmp_path))
    assert set(printed["r2_after"]) == {"theta_u"}
    assert all(v is not None for v in printed["r2_after"].values()) or printed["warnings"]
    assert "params" in loads_strict((tmp_path / "m.json").read_text(encoding="utf-8"))

    staged = loads_strict(_cli("identify-staged", "--upper", "up.csv", "--out", "st.json", "--json", cwd=tmp_path))
    assert [s["stage"] for s in staged["stages"]] == ["upper"]
    assert "km" in loads_strict((tmp_path / "st.json").read_text(encoding="utf-8"))
    for path in tmp_path.rglob("*.json"):  # and nothing else slipped through
        loads_strict(path.read_text(encoding="utf-8"))
        json.loads(path.read_text(encoding="utf-8"))
