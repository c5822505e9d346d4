"""The Python API refuses what the command line refuses, in the same words, before any work."""

from __future__ import annotations

import numpy as np
import pytest

from drillgym import simulate, simulate_batch
from drillgym.errors import EffectError, InputError, InputTypeError
from drillgym.run_setup import U_LIMIT

SHORT = 0.02  # s: every case is refused before a step is taken, or runs this long


@pytest.mark.parametrize(
    ("arguments", "error", "words"),
    [
        ({"u": 1e6}, InputError, "beyond the model's range |u| <= 50 V"),
        ({"u": -(U_LIMIT + 1)}, InputError, "-51 V"),
        ({"u": "abc"}, InputTypeError, "u must be a voltage (V)"),
        ({"u": None}, InputTypeError, "got None"),
        ({"u": True}, InputTypeError, "got True"),
        ({"u": [1.0, 2.0, "x"]}, InputTypeError, "u must hold numbers (V)"),
        ({"u": lambda t: "x"}, InputTypeError, "the value of the input function u(t)"),
        ({"u": (np.array([0.0, 0.01]), np.array([1.0, 60.0]))}, InputError, "60 V (trajectory 0, entry 1)"),
        ({"duration": "2"}, InputTypeError, "duration must be a number (s), got '2' of type str"),
        ({"duration": None}, InputTypeError, "duration must be a number"),
        ({"dt": "0.001"}, InputTypeError, "dt must be a number (s)"),
        ({"dt": np.float64(0.5)}, InputError, "dt must be in (0, 0.1] s, got 0.5"),
        ({"record_every": 2.5}, InputTypeError, "record_every must be a whole number, got 2.5"),
        ({"record_every": "2"}, InputTypeError, "record_every must be a whole number"),
        ({"record_every": 0}, InputError, "record_every must be >= 1, got 0"),
        ({"alpha0": "1"}, InputTypeError, "alpha0 must be a number"),
        ({"alpha0": None}, InputTypeError, "alpha0"),
        ({"alpha0": float("nan")}, InputError, "alpha0 must be finite"),
        ({"alpha0": [0.1, 0.2]}, InputError, "use simulate_batch for several"),
        ({"x0": ["a"] * 8}, InputTypeError, "the initial state x0 must hold numbers"),
        ({"effects": 3}, EffectError, "effects must be an effect"),
    ],
)
def test_simulate_refuses_a_bad_argument_in_one_line_naming_it(arguments, error, words):
    call = {"u": 1.0, "duration": SHORT, **arguments}
    with pytest.raises(error) as refused:
        simulate("torsional", **call)
    message = str(refused.value)
    assert words in message
    assert "\n" not in message and "np.float64" not in message


def test_the_voltage_limit_is_the_command_lines():
    """50 V passes, 50.001 V does not: the same limit as ``simulate --u`` and a recording's u column."""
    assert np.isfinite(simulate("torsional", U_LIMIT, SHORT).final_state).all()
    with pytest.raises(InputError):
        simulate("torsional", U_LIMIT + 1e-3, SHORT)


def test_a_batch_refuses_one_bad_run_naming_it():
    u = np.ones((3, 20))
    u[2, 7] = 75.0
    with pytest.raises(InputError, match=r"75 V \(trajectory 2, step 7\)"):
        simulate_batch("torsional", u, SHORT)


def test_numpy_scalars_are_numbers():
    run = simulate("torsional", np.float32(1.0), np.float64(SHORT), dt=np.float64(1e-3), record_every=np.int64(2))
    assert run.data.shape[0] == 11
