"""The compiled code's floating-point flags give the same bits however it was compiled.

LLVM applies fast-math flags that change values (``contract``: a multiply and an add fused; ``reassoc``,
``arcp``, ``afn``) where it sees them together, and it sees more of them where it inlined a callee: a kernel
compiled in a process that compiled its callees too, and one compiled beside callees loaded from numba's cache,
gave different last bits, which an identification amplified into a different model of the same recording.  Every
numba function of drillgym and of the controllers' compiled laws takes :data:`drillgym.vmath.FASTMATH` (flags
that change no finite value) or none.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from drillgym.effects.hook_context import JIT
from drillgym.vmath import FASTMATH

ROOT = Path(__file__).resolve().parent.parent
SOURCES = sorted([*ROOT.glob("drillgym/**/*.py"), *ROOT.glob("controllers/**/*.py")])
VALUE_SAFE = {"nnan", "ninf", "nsz"}


def _fastmath_values(path: Path) -> list[tuple[int, ast.expr]]:
    """The ``fastmath=`` arguments of every call in a source file, with their lines."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [
        (node.lineno, kw.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        for kw in node.keywords
        if kw.arg == "fastmath"
    ]


def test_the_flags_change_no_finite_value():
    assert FASTMATH <= VALUE_SAFE


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_numba_function_takes_the_value_safe_flags(path):
    for line, value in _fastmath_values(path):
        shown = ast.unparse(value)
        assert shown == "FASTMATH" or (isinstance(value, ast.Constant) and value.value is False), (
            f"{path.relative_to(ROOT)}:{line}: fastmath={shown}; use drillgym.vmath.FASTMATH"
        )


def test_the_effects_functions_are_compiled_with_them():
    decorator = ast.parse(JIT, mode="eval").body
    value = next(kw.value for kw in decorator.keywords if kw.arg == "fastmath")
    assert ast.literal_eval(value) == FASTMATH


def test_the_check_finds_a_value_changing_flag(tmp_path):
    bad = tmp_path / "kernel.py"
    bad.write_text("from numba import njit\n\n@njit(fastmath=True)\ndef f(x):\n    return x * 2.0 + 1.0\n")
    ((line, value),) = _fastmath_values(bad)
    assert line == 3 and ast.unparse(value) == "True"


def test_the_kernels_compiled_variants_give_the_same_bits():
    """The lane kernel compiled to record every column and compiled to record two, the command a constant per lane
    and a table: one trajectory (under contraction they parted by about 1e-14)."""
    import numpy as np

    from drillgym import simulate_batch

    u = np.linspace(0.5, 4.5, 8)
    every = simulate_batch("torsional", u, 3.0, record_every=10)
    two = simulate_batch("torsional", u, 3.0, record_every=10, record=("t", "omega_l"))
    table = simulate_batch("torsional", np.repeat(u[:, None], 3000, axis=1), 3.0, record_every=10)
    np.testing.assert_array_equal(two.omega_l, every.omega_l)
    np.testing.assert_array_equal(table.omega_l, every.omega_l)
