"""What Python an effect function may use: each construct tried, compiled as the kernels compile it
(numba nopython, inlined, scalar and lane variants), its result compared with plain Python; what numba refuses
is refused in one line before any kernel is built.  docs/EFFECTS.md's table is this one."""

import math
import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from drillgym.effects import EffectError
from drillgym.effects.compile_check import check_effect_compiles, compile_function
from drillgym.effects.registry import load_class_from_file

DOC = Path(__file__).resolve().parents[1] / "docs" / "EFFECTS.md"

HEADER = """
import math

import numpy as np
from numba import njit

from drillgym.effects import Force

GAIN = 0.25


@njit
def doubled(x):
    return 2.0 * x


def plain_doubled(x):
    return 2.0 * x
"""

#: (the docs table's label, the body of torque(omega_u), works)
CONSTRUCTS = [
    (
        "`math` functions",
        "return math.tanh(omega_u) + math.exp(-omega_u * omega_u) + math.copysign(1.0, omega_u)",
        True,
    ),
    (
        "numpy ufuncs on floats",
        "return np.tanh(omega_u) + np.sign(omega_u) + np.abs(omega_u) + np.maximum(omega_u, 0.5)",
        True,
    ),
    ("`np.clip` on a float", "return np.clip(omega_u, -1.0, 1.0)", False),
    (
        "`abs`, `min`, `max`, `round`, `int`, `float`",
        "return abs(omega_u) + min(omega_u, 1.0) + max(omega_u, 0.0) + float(int(omega_u))",
        True,
    ),
    (
        "`if` / `elif` / `else`, several `return`s",
        "if omega_u > 0.4:\n    return omega_u - 0.4\nelif omega_u < -0.4:\n    return omega_u + 0.4\nreturn 0.0",
        True,
    ),
    ("conditional expressions", "return omega_u if omega_u > 0.0 else -omega_u", True),
    (
        "the power operator `**` (a fractional or variable exponent vectorised in the lane variant)",
        "return abs(omega_u) ** 1.5 + omega_u ** 2 + 2.0 ** omega_u + (-omega_u) ** 3.0 + abs(omega_u) ** GAIN",
        True,
    ),
    ("local variables, tuple unpacking", "a, b = omega_u, 2.0 * omega_u\nc = a * b\nreturn c - a", True),
    (
        "`for` over `range`, `while`",
        "s = 0.0\nfor k in range(1, 4):\n    s += math.sin(k * omega_u) / k\nwhile s > 1.0:\n    s = s / 2.0\nreturn s",
        True,
    ),
    ("module-level constants (frozen when the kernels are compiled)", "return GAIN * omega_u", True),
    ("helpers decorated with `numba.njit`", "return doubled(omega_u)", True),
    ("a `lambda` or a nested `def`", "sq = lambda z: z * z\nreturn sq(omega_u)", True),
    (
        "a list or `np.array` inside the function (allocated at every call: slow)",
        "a = [omega_u, 2.0 * omega_u]\nb = np.array([omega_u, 1.0])\nreturn a[0] + a[1] + b.sum()",
        True,
    ),
    ("plain Python helpers (not decorated)", "return plain_doubled(omega_u)", False),
    ("`try` / `except`", "try:\n    return 1.0 / omega_u\nexcept ZeroDivisionError:\n    return 0.0", False),
    ("`import` inside the function", "import cmath\nreturn omega_u", False),
    ("a path that returns nothing", "if omega_u > 100.0:\n    return omega_u", False),
    ("returning an array", "return np.array([omega_u])", False),
]


def _effect(tmp_path: Path, k: int, body: str):
    path = tmp_path / f"construct_{k}.py"
    fn = "    def torque(omega_u):\n" + textwrap.indent(body, " " * 8) + "\n"
    path.write_text(
        HEADER + f"\n\nclass Construct{k}(Force):\n    name = 'construct_{k}'\n    acts_on = 'upper'\n\n" + fn
    )
    return load_class_from_file(path, f"construct_{k}")


@pytest.mark.parametrize("k", range(len(CONSTRUCTS)), ids=[c[0] for c in CONSTRUCTS])
def test_each_construct_compiles_as_the_docs_say_and_gives_what_python_gives(tmp_path, k):
    label, body, works = CONSTRUCTS[k]
    cls = _effect(tmp_path, k, body)
    f = cls.defined_functions()["torque"]
    if works:
        check_effect_compiles(cls)
        for lane in (False, True):
            compiled = compile_function(f, 1, lane)
            for w in (-1.3, 0.2, 0.7, 2.5):
                assert compiled(w) == pytest.approx(f(w), rel=1e-6, abs=1e-12), (label, lane, w)
    else:
        with pytest.raises(EffectError) as err:
            check_effect_compiles(cls)
        text = str(err.value)
        assert "\n" not in text and f"construct_{k}.py: effect 'construct_{k}': torque()" in text
        assert "cannot be compiled into the kernels" in text or "when compiled, expected 1 float" in text
        assert "\x1b[" not in text


def test_the_docs_table_lists_exactly_these_constructs():
    text = DOC.read_text(encoding="utf-8")
    rows = re.findall(r"^\| (.+?) \| (yes|no) \|", text, flags=re.M)
    assert rows == [(label, "yes" if works else "no") for label, _, works in CONSTRUCTS]


FEATURES = '''
    def torque(omega_u):
        """0 when every construct computes what plain arithmetic does (then the run is the base model's)."""
        a, b = GAIN * doubled(omega_u), 0.0
        for k in range(2):
            b += 0.25 * omega_u
        kink = omega_u - 0.4 if omega_u > 0.4 else (omega_u + 0.4 if omega_u < -0.4 else 0.0)
        smooth = np.tanh(omega_u) - math.tanh(omega_u) + abs(min(omega_u, 0.0)) - max(-omega_u, 0.0)
        return 3.0 * (a - b + smooth + kink - kink)
'''


@pytest.mark.slow
def test_the_constructs_run_in_the_kernels_of_a_simulation_single_and_batched(tmp_path):
    """An njit helper, a module constant, a loop, conditional expressions, numpy and math, inside the real
    kernels (scalar single run and SIMD lane batch): the torque they compute is zero, so the runs are the base
    model's; a construct compiled to something else would move the disc differently."""
    from drillgym import simulate, simulate_batch
    from drillgym.simulator import LANES_MIN_BATCH

    path = tmp_path / "features.py"
    path.write_text(HEADER + "\n\nclass Features(Force):\n    name = 'features'\n    acts_on = 'upper'\n" + FEATURES)
    cls = load_class_from_file(path, "features")
    f = cls.defined_functions()["torque"]
    assert all(f(w) == pytest.approx(0.0, abs=1e-15) for w in (-2.0, -0.3, 0.0, 0.5, 3.0))
    u = (np.array([0.0, 0.3, 0.6]), np.array([1.5, -2.0, 0.8]))
    base = simulate("upper", u, 1.0)
    run = simulate("upper", u, 1.0, effects=[f"{path}:features"])
    np.testing.assert_allclose(run.omega_u, base.omega_u, rtol=0, atol=1e-9)
    batch = simulate_batch("upper", u, 1.0, n_batch=LANES_MIN_BATCH, effects=[f"{path}:features"])
    np.testing.assert_allclose(batch.omega_u[0], base.omega_u, rtol=0, atol=1e-9)


def test_a_math_domain_error_is_nan_in_the_kernels_not_an_exception():
    """Python raises ValueError for math.log of a negative number; compiled as the kernels compile it (numpy
    error model) it gives NaN, which a y != y test still sees with this numba."""

    def log_shifted(omega_u):
        return math.log(omega_u - 10.0)

    def is_nan(omega_u):
        y = math.log(omega_u - 10.0)
        return 1.0 if y != y else 0.0

    with pytest.raises(ValueError):
        log_shifted(0.5)
    assert math.isnan(compile_function(log_shifted, 1)(0.5))
    assert compile_function(is_nan, 1)(0.5) == 1.0 and compile_function(is_nan, 1)(20.0) == 0.0


def test_a_function_of_more_arguments_than_the_kernels_pass_is_refused_in_words(tmp_path):
    from drillgym.effects.compile_check import MAX_ARGUMENTS

    n = MAX_ARGUMENTS  # omega_u and n parameters: one more than the kernels pass
    params = ", ".join(f"p{i}" for i in range(n))
    decl = "\n".join(f"        Parameter('p{i}', '-', -1.0, 1.0, 0.0, 0.1)," for i in range(n))
    path = tmp_path / "wide.py"
    path.write_text(
        "from drillgym.effects import Force, Parameter\n\n\nclass Wide(Force):\n    name = 'wide'\n"
        f"    acts_on = 'upper'\n    parameters = (\n{decl}\n    )\n\n"
        f"    def torque(omega_u, {params}):\n        return omega_u * ({' + '.join(f'p{i}' for i in range(n))})\n"
    )
    cls = load_class_from_file(path, "wide")
    with pytest.raises(EffectError) as err:
        check_effect_compiles(cls)
    assert f"takes {n + 1} arguments, more than the {MAX_ARGUMENTS}" in str(err.value)
