"""The import contracts of pyproject.toml cover the whole physics core.

``lint-imports`` (run by ``make test``) checks the contracts; this test checks that the core
contract names every module of the core, so a new module cannot escape it unnoticed.
"""

from __future__ import annotations

from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

ROOT = Path(__file__).resolve().parents[1]
OUTSIDE_CORE = {"drillgym.cli", "drillgym.commands"}


def _contracts() -> dict[str, dict]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    return {c["id"]: c for c in config["contracts"]}


def test_core_contract_names_every_core_module():
    core = set(_contracts()["core"]["source_modules"])
    package = ROOT / "drillgym"
    found = {f"drillgym.{p.stem}" for p in package.glob("*.py") if p.name != "__init__.py"}
    found |= {f"drillgym.{p.parent.name}" for p in package.glob("*/__init__.py")}
    assert core == found - OUTSIDE_CORE


def test_core_contract_forbids_the_command_line_and_the_upper_packages():
    forbidden = set(_contracts()["core"]["forbidden_modules"])
    assert forbidden == OUTSIDE_CORE | {"controllers", "agents", "hw"}


def test_packages_stand_in_layers():
    assert _contracts()["packages"]["layers"] == ["hw", "agents", "controllers", "drillgym"]
