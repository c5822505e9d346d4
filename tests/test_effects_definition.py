"""Writing an effect: what is accepted, what is refused (one line naming the file, the effect and the
problem), where effects come from (library, files, entry points), and the on-disk kernel cache."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from drillgym import simulate
from drillgym.effects import LIBRARY, EffectError, available_effects, compose
from drillgym.effects.base import FRICTION_VOCABULARY, MEASUREMENT_CHANNELS, VOCABULARY
from drillgym.effects.codegen import hooks_source
from drillgym.effects.quantities import (
    KIND_FUNCTIONS,
    base_parameters_markdown,
    fixed_quantities,
    quantities_markdown,
    quantity_table,
)

ROOT = Path(__file__).resolve().parents[1]


def write_effect(tmp_path: Path, body: str, name: str = "my_effect.py") -> Path:
    path = tmp_path / name
    path.write_text(
        "from drillgym.effects import Force, Friction, Input, Delay, Measurement, Parameter, State\n"
        "import math\n\n" + textwrap.dedent(body)
    )
    return path


GOOD = """
class UpperBump(Friction):
    '''A Stribeck bump at the upper disc.'''
    name = "upper_bump"
    disc = "upper"
    parameters = (Parameter("bump", "N m", 0.0, 1.0, 0.05, 0.01, "height of the bump"),)

    def slip(T, direction, speed, bump):
        return T + direction * bump * math.exp(-speed)

    def stick(lo, hi, bump):
        return lo - bump, hi + bump
"""


def test_library_has_the_ten_effects_and_lists_them():
    assert len(LIBRARY) == 10
    assert set(LIBRARY) <= set(available_effects())
    for cls in LIBRARY.values():
        assert cls.explanation and cls.signature and cls.parameters
        for p in cls.parameters:
            assert p.lo < p.hi and p.lo <= p.guess <= p.hi and p.scale > 0 and p.unit


def test_a_user_friction_effect_on_the_upper_disc_is_compiled_and_acts(tmp_path):
    path = write_effect(tmp_path, GOOD)
    base = simulate("upper", 0.2, 2.0)
    assert base.omega_u[-1] > 0.0  # km u = 0.86 N m exceeds the upper stick level 0.374 N m: it turns
    bump = simulate("upper", 0.2, 2.0, effects=[f"{path}:upper_bump"], effect_params={"bump": 0.6})
    assert np.all(bump.omega_u == 0.0)  # the wider stick set holds the disc


def test_unknown_effect_name_lists_the_known_ones():
    with pytest.raises(EffectError, match="unknown effect 'motor_lagg'.*motor_lag"):
        compose(["motor_lagg"])


@pytest.mark.parametrize(
    "body, message",
    [
        (
            "class Broken(Force):\n    name = 'broken'\n    acts_on = 'string'\n"
            "    def torque(alpha:\n        return 0\n",
            "does not import",
        ),
        ("raise RuntimeError('no licence')\n", "does not import.*RuntimeError: no licence"),
        ("import sys\nsys.exit(3)\n", r"calls sys.exit\(3\) when imported \(line 6\)"),
        (
            "class Middle(Force):\n    name = 'middle'\n    acts_on = 'middle_disc'\n"
            "    def torque(alpha):\n        return alpha\n",
            "acts_on = 'middle_disc' is not a coordinate",
        ),
        (
            "class Odd(Force):\n    name = 'odd'\n    acts_on = 'lower'\n"
            "    def torque(omega_x):\n        return omega_x\n",
            "unknown quantity/coordinate 'omega_x'",
        ),
        (
            "class Loose(Force):\n    name = 'loose'\n    acts_on = 'lower'\n"
            "    parameters = (Parameter('c', '-', None, 1.0, 0.0, 0.1),)\n"
            "    def torque(alpha, c):\n        return c * alpha\n",
            "needs a finite lo",
        ),
        (
            "class Nan(Force):\n    name = 'nan_effect'\n    acts_on = 'lower'\n"
            "    def torque(omega_l):\n        return math.log(omega_l)\n",
            "fails at a typical state|not finite",
        ),
        (
            "class Nan2(Force):\n    name = 'nan2'\n    acts_on = 'lower'\n"
            "    def torque(omega_l):\n        return math.sqrt(abs(omega_l)) * float('nan')\n",
            "not finite",
        ),
        (
            "class Selfish(Force):\n    name = 'selfish'\n    acts_on = 'lower'\n"
            "    def torque(self, alpha):\n        return alpha\n",
            "without self",
        ),
        (
            "class Clash(Force):\n    name = 'clash'\n    acts_on = 'lower'\n"
            "    parameters = (Parameter('Ts', 'N m', 0.0, 1.0, 0.1, 0.1),)\n"
            "    def torque(Ts):\n        return Ts\n",
            "already taken",
        ),
        (
            "class NoState(Input):\n    name = 'nostate'\n    states = (State('z', 'V'),)\n"
            "    def voltage(u, z):\n        return z\n",
            "defines derivative",
        ),
        (
            "class BadLag(Input):\n    name = 'badlag'\n    states = (State('z', 'V'),)\n"
            "    parameters = (Parameter('tau', 's', 0.0, 1.0, 0.1, 0.1),)\n    lag = {'z': 'tau'}\n"
            "    def derivative(u, z, tau):\n        return (u - z) / tau\n"
            "    def voltage(z):\n        return z\n",
            "lag time constant 'tau' needs a lower bound > 0",
        ),
        (
            "class Biased(Force):\n    name = 'biased'\n    acts_on = 'lower'\n"
            "    parameters = (Parameter('c', '-', -1.0, 1.0, 0.0, 0.1, neutral=0.0),)\n"
            "    def torque(omega_l, c):\n        return np.float64(c * omega_l + 0.01)\n",
            r"a Force at its neutral values must add no torque: torque\(\) gives 0.01 N m on the lower disc "
            r"at omega_l = 0 rad/s \(declared neutral: c = 0\); drop neutral= or fix the function",
        ),
        (
            "class WideZone(Input):\n    name = 'wide_zone'\n"
            "    parameters = (Parameter('u0', 'V', 0.0, 1.0, 0.4, 0.1, neutral=0.0),)\n"
            "    def voltage(u, u0):\n        return u - 0.4 * math.copysign(1.0, u) if abs(u) > u0 else 0.0\n",
            r"an Input effect at its neutral values must pass the voltage through unchanged: voltage\(\) gives "
            r"2.1 V for 2.5 V \(declared neutral: u0 = 0\)",
        ),
        (
            "class Drag(Friction):\n    name = 'drag'\n"
            "    parameters = (Parameter('cq', 'N m s^2', 0.0, 1.0, 0.0, 0.01, neutral=0.0),)\n"
            "    def slip(T, direction, speed, cq):\n        return T + direction * (cq + 0.02) * speed\n",
            r"a Friction effect at its neutral values must leave the slip torque unchanged: slip\(\) gives "
            r"0.45 N m for T = 0.3 N m at direction = 1, speed = 7.5 rad/s",
        ),
        (
            "class Grip(Friction):\n    name = 'grip'\n"
            "    parameters = (Parameter('g', '-', 0.0, 1.0, 0.0, 0.01, neutral=0.0),)\n"
            "    def stick(lo, hi, g):\n        return lo * (1.0 + g) - 0.05, hi\n",
            r"must leave the stick set unchanged: stick\(\) gives \(-0.35, 0.3\) N m "
            r"for \(lo, hi\) = \(-0.3, 0.3\) N m",
        ),
        (
            "class Warm(Friction):\n    name = 'warm'\n"
            "    parameters = (Parameter('drift_w', '1/s', -0.1, 0.1, 0.0, 0.01, neutral=0.0),)\n"
            "    def level(t, drift_w):\n        return 1.1 + drift_w * t\n",
            r"must leave the friction level unchanged: level\(\) gives 1.1 instead of 1 at t = 0 s",
        ),
        (
            "class Late(Delay):\n    name = 'late'\n"
            "    parameters = (Parameter('d', 's', 0.0, 0.1, 0.0, 0.01, neutral=0.0),)\n"
            "    def delay(d):\n        return d + 0.001\n",
            r"a Delay effect at its neutral values must delay by nothing: delay\(\) gives 0.001 s",
        ),
        (
            "class Skewed(Measurement):\n    name = 'skewed'\n    channels = ('theta_l',)\n"
            "    parameters = (Parameter('g', '-', -0.1, 0.1, 0.0, 0.01, neutral=0.0),)\n"
            "    def measure(theta_l, g):\n        return theta_l * (1.0 + g) + 0.01\n",
            r"a Measurement effect at its neutral values must leave the reading unchanged: measure\(\) gives "
            r"theta_l = 0.01 rad for 0 rad",
        ),
        (
            "class Ratio(Force):\n    name = 'ratio'\n    acts_on = 'upper'\n"
            "    parameters = (Parameter('c', '-', 0.0, 1.0, 0.5, 0.1, neutral=0.0),)\n"
            "    def torque(omega_u, c):\n        return omega_u * c / c\n",
            r"torque\(\) fails at its declared neutral values \(c = 0\) at omega_u = 0 rad/s: ZeroDivisionError",
        ),
        (
            "class Listy(Force):\n    name = 'listy'\n    acts_on = 'upper'\n"
            "    def torque(omega_u):\n        return np.array([omega_u, 1.0])\n",
            r"torque\(\) returns ndarray \[0. 1.\], not a number",
        ),
        (
            "import os\nos._exit(0)\n\nclass Gone(Force):\n    name = 'gone'\n    acts_on = 'upper'\n"
            "    def torque(omega_u):\n        return 0.0\n",
            r"effect file calls os._exit\(0\) when imported \(line 6\)",
        ),
        (
            "class Twin(Force):\n    name = 'twin'\n    acts_on = 'upper'\n"
            "    def torque(omega_u):\n        return 0.0\n\nclass Other(Twin):\n    name = 'twin'\n",
            r"2 effects are named 'twin' \(Twin, Other\): give each its own name",
        ),
        (
            "class Outside(Force):\n    name = 'outside'\n    acts_on = 'lower'\n"
            "    parameters = (Parameter('c', '-', 0.0, 1.0, 0.5, 0.1, neutral=-1.0),)\n"
            "    def torque(omega_l, c):\n        return c * omega_l\n",
            "neutral = -1.0 is not a number within its bounds",
        ),
    ],
)
def test_bad_effect_files_get_one_line_errors_naming_file_and_problem(tmp_path, body, message):
    path = tmp_path / "bad_effect.py"
    path.write_text(
        "from drillgym.effects import Delay, Force, Friction, Input, Measurement, Parameter, State\n"
        "import math\nimport numpy as np\n\n" + body
    )
    name = body.split("name = '")[1].split("'")[0] if "name = '" in body else "x"
    with pytest.raises(EffectError, match=message) as err:
        compose([f"{path}:{name}"])
    text = str(err.value)
    assert "\n" not in text and "bad_effect.py" in text
    assert "np.float64(" not in text and "array(" not in text


def test_missing_effect_in_a_file_and_missing_file(tmp_path):
    path = write_effect(tmp_path, GOOD)
    with pytest.raises(EffectError, match="no effect named 'other'.*upper_bump"):
        compose([f"{path}:other"])
    with pytest.raises(EffectError, match="not found"):
        compose([f"{tmp_path}/nowhere.py:x"])
    with pytest.raises(EffectError, match=r"say which effect.*\(it defines: upper_bump\)"):
        compose([str(path)])
    with pytest.raises(EffectError, match="nowhere.py: effect file not found"):  # not "say which effect"
        compose([f"{tmp_path}/nowhere.py"])


def test_effect_values_are_checked_against_their_bounds():
    with pytest.raises(ValueError, match="'tau_m' = 9.0 s is outside"):
        compose(["motor_lag"], {"tau_m": 9.0})
    with pytest.raises(ValueError, match="unknown effect parameter 'tau'"):
        compose(["motor_lag"], {"tau": 0.1})
    with pytest.raises(EffectError, match="given twice"):
        compose(["motor_lag", "motor_lag"])


def test_cli_refuses_a_bad_effect_in_one_line(tmp_path):
    path = tmp_path / "bad.py"
    path.write_text("this is not python\n")
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "drillgym.cli",
            "simulate",
            "--u",
            "1",
            "--duration",
            "1",
            "--out",
            str(tmp_path / "o.csv"),
            "--add-effect",
            f"{path}:x",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and "bad.py" in lines[0] and "does not import" in lines[0]
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "drillgym.cli",
            "simulate",
            "--u",
            "1",
            "--duration",
            "1",
            "--out",
            str(tmp_path / "o.csv"),
            "--effect-param",
            "tau_m=0.1",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 2 and "no effect added" in r.stderr


def test_effects_command_lists_and_validates(tmp_path):
    r = subprocess.run([sys.executable, "-m", "drillgym.cli", "effects"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0
    for name in LIBRARY:
        assert name in r.stdout
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "drillgym.cli",
            "effects",
            "--show",
            f"{ROOT}/examples/effects/string_cubic.py:string_cubic",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and "c3" in r.stdout and "1/rad^2" in r.stdout


def test_entry_point_effects_are_found_by_name(tmp_path, monkeypatch):
    """An installed package provides effects through the entry-point group drillgym.effects."""
    pkg = tmp_path / "site"
    pkg.mkdir()
    (pkg / "rig_extras.py").write_text(
        "from drillgym.effects import Force, Parameter\n\n"
        "class Wind(Force):\n    name = 'wind'\n    acts_on = 'upper'\n"
        "    parameters = (Parameter('gust', 'N m', 0.0, 1.0, 0.1, 0.01),)\n"
        "    def torque(gust):\n        return -gust\n"
    )
    dist = pkg / "rig_extras-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rig-extras\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[drillgym.effects]\nwind = rig_extras:Wind\n")
    monkeypatch.syspath_prepend(str(pkg))
    assert "wind" in available_effects()
    comp, vals = compose(["wind"])
    assert comp.param_names[-1] == "gust" and vals == {"gust": 0.1}


def test_generated_code_reads_like_the_composition():
    comp, _ = compose(["motor_lag", "string_damping"])
    src = hooks_source(comp)
    assert "_e0_derivative(u, y[8]" in src and "u = _e0_voltage(y[8])" in src
    assert "_Qs += _e1_torque((y[3] - y[2])" in src


def test_an_effect_declaring_where_it_vanishes_is_switched_outside_its_lane_loop():
    """string_damping declares neutral=0: its lane loop runs only when the batch's switch row is on
    (tested outside the loop), and the scalar kernel tests the run's own value; the user's backlash
    declares nothing and always runs."""
    comp, _ = compose(["string_damping", f"{ROOT}/examples/effects/string_backlash.py:string_backlash"])
    src = hooks_source(comp)
    row = comp.n_params  # the first switch row, after the parameters
    dtheta = comp.param_index("dtheta")
    guard = f"if (cfg == 1 or cfg == 2 or cfg == 3 or cfg == 4) and (PT[{row}, 0] != 0.0):"
    assert guard + "\n        for k in range(n):" in src
    assert f"and (p[{dtheta}] != 0.0):\n        _Qs += _e0_torque" in src
    assert f"PT[{row + 1}," not in src  # one switch only
    assert "# string_backlash\n    for k in range(n):" in src


@pytest.mark.slow
def test_kernel_cache_is_keyed_by_content_never_stale(tmp_path):
    """The same effect file edited between two runs: the second run sees the new physics (a new cached
    package), and a third identical run reuses the second's cache."""
    path = tmp_path / "push.py"
    script = (
        "import sys; from drillgym import simulate; from drillgym.effects import compose\n"
        f"c, _ = compose(['{path}:push']); tr = simulate('upper', 0.0, 1.0, effects=c)\n"
        "print(tr.omega_u[-1], c.kernels.package)"
    )
    env = dict(os.environ, DRILLGYM_KERNEL_CACHE=str(tmp_path / "cache"))

    def run(gain: float) -> tuple[float, str]:
        path.write_text(
            "from drillgym.effects import Force\n\nclass Push(Force):\n    name = 'push'\n"
            f"    acts_on = 'upper'\n\n    def torque(t):\n        return {gain}\n"
        )
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
        assert out.returncode == 0, out.stderr
        w, pkg = out.stdout.split()
        return float(w), pkg

    w1, p1 = run(1.0)
    w2, p2 = run(2.0)
    w3, p3 = run(2.0)
    assert p1 != p2 and p2 == p3
    assert w2 > w1 > 0.0 and w3 == w2


def test_the_docs_list_exactly_the_quantities_a_function_may_ask_for():
    """docs/EFFECTS.md holds the generated tables verbatim, and the refusal of an unknown argument lists the same
    fixed quantities for that kind and function."""
    text = (ROOT / "docs" / "EFFECTS.md").read_text(encoding="utf-8")
    assert quantities_markdown() in text and base_parameters_markdown() in text
    names = {q.name for q in quantity_table()}
    assert names == set(VOCABULARY) | set(FRICTION_VOCABULARY) | set(MEASUREMENT_CHANNELS)
    for kind, functions in KIND_FUNCTIONS.items():
        for fn in functions:
            assert set(fixed_quantities(kind, fn)) <= names
            listed = {q.name for q in quantity_table() if f"{kind}.{fn}" in q.functions}
            assert listed == set(fixed_quantities(kind, fn)), (kind, fn)


def test_an_unknown_argument_is_refused_with_what_that_function_may_use(tmp_path):
    path = write_effect(
        tmp_path,
        "class Grippy(Friction):\n    name = 'grippy'\n"
        "    parameters = (Parameter('g', '-', 0.0, 1.0, 0.1, 0.1),)\n"
        "    def stick(lo, hi, speed, g):\n        return lo - g * speed, hi\n",
    )
    with pytest.raises(EffectError) as err:
        compose([f"{path}:grippy"])
    text = str(err.value)
    assert "stick() asks for unknown quantity/coordinate 'speed'" in text
    assert "its parameters (g)" in text and "Ju, km" in text
    assert text.endswith(f"and: {', '.join(fixed_quantities('Friction', 'stick'))} (docs/EFFECTS.md lists them)")


def test_an_effect_defined_inside_a_function_is_refused_in_one_line():
    """The compiled kernels import an effect by its module and name: one defined in a function's body cannot be
    imported, and is refused before any code is generated."""
    from drillgym.effects import Input, Parameter, compose
    from drillgym.errors import EffectError

    class Local(Input):
        name = "local_offset"
        parameters = (Parameter("u_off", "V", -1.0, 1.0, 0.0, 0.05, "offset", neutral=0.0),)

        def voltage(u, u_off):
            return u + u_off

    with pytest.raises(EffectError, match="defined inside a function; define it at a module's top level"):
        compose([Local])


def test_an_effect_file_is_compiled_once_wherever_it_lies_and_whatever_its_guesses(tmp_path, monkeypatch):
    """The kernels depend on an effect file's code, not on its path, docstrings or parameters' guesses: a copy
    elsewhere with other guesses (a model folder copied, a candidate written for another recording) runs in the
    package the first one compiled, with the same physics; an edit of the code or of a module-level constant the
    code reads makes a new package."""
    from drillgym.effects.codegen import package_name

    monkeypatch.setenv("DRILLGYM_KERNEL_CACHE", str(tmp_path / "cache"))

    def written(folder: str, guess: float, doc: str, gain: str = "2.0", body: str = "GAIN * push") -> Path:
        (tmp_path / folder).mkdir(exist_ok=True)
        path = tmp_path / folder / "push.py"
        path.write_text(
            f"from drillgym.effects import Force, Parameter\n\nGAIN = {gain}\n\n\nclass Push(Force):\n"
            f"    '''{doc}'''\n    name = 'push'\n    acts_on = 'upper'\n"
            f"    parameters = (Parameter('push', 'N m', 0.0, 5.0, {guess}, 0.1, '{doc}'),)\n\n"
            f"    def torque(push):\n        # {doc}\n        return {body}\n"
        )
        return path

    def key(path: Path) -> str:
        comp, _ = compose([f"{path}:push"])
        return package_name(comp, hooks_source(comp))

    first = written("a", 0.5, "a push on the upper disc")
    copy = written("b", 1.25, "the same push, guessed again")
    assert key(first) == key(copy)
    assert key(written("c", 0.5, "x", body="GAIN * push * push")) != key(first)
    assert key(written("d", 0.5, "x", gain="3.0")) != key(first)
    runs = []
    for path in (first, copy):
        comp, _ = compose([f"{path}:push"])
        runs.append(simulate("upper", 0.0, 0.5, effects=comp, effect_params={"push": 0.8}))
    assert not (tmp_path / "cache" / key(first) / "effect_1.py").exists()
    assert (tmp_path / "cache" / key(first) / "effect_0.py").read_text() == first.read_text()
    assert runs[0].omega_u[-1] > 0.0 and np.array_equal(runs[0].omega_u, runs[1].omega_u)
    assert len(list((tmp_path / "cache").glob("_dgk_*"))) == 1
