"""The observer's, lqg's and lqg-2enc's compiled laws on a model with effects against the step-by-step reference.

The model has a motor lag and an input delay (library effects: 5 ms at a 2 ms period, so a line of three past
commands and a fractional delay that splits the period) and a dead zone (a user file: its static input map is
inverted in the command).  Tolerances: one period of the compiled law from the reference controller's state agrees
with ``act`` to 1e-12 (V, and relative on the estimates); whole runs with exact angles agree to 1e-9 relative on
omega_l over 1.5 s (the closed loop amplifies round-off, tests/test_compiled_loop.py).
"""

import numpy as np
import pytest
from test_compiled_loop import assert_laws_match_act
from test_controllers_any_model import SCALE_FILE

import controllers
from controllers.evaluation.runner import run_closed_loop
from drillgym import Model, RigParams

EFFECTS = ("motor_lag", "input_delay", "examples/effects/motor_dead_zone.py:dead_zone")
VALUES = {"tau_m": 0.03, "delay": 0.005, "u0": 0.3}
PLANT = {"effects": list(EFFECTS), "effect_params": VALUES}
REF = np.array([1.5, 3.0, 5.0])


@pytest.fixture(scope="module")
def model():
    return Model(RigParams(), EFFECTS, VALUES)


@pytest.mark.parametrize("name", ["observer", "lqg", "lqg-2enc"])
def test_one_period_of_the_law_is_act_along_a_reference_run(name, model):
    assert_laws_match_act(name, REF, 0.4, PLANT, model=model)


@pytest.mark.parametrize("name", ["observer", "lqg", "lqg-2enc"])
def test_compiled_runs_on_a_model_with_effects_match_the_reference(name, model):
    runs = []
    for compiled in (False, True):
        c = controllers.make(name, config="torsional", omega_ref=REF, model=model)
        runs.append(run_closed_loop(c, "torsional", REF, 1.5, compiled=compiled, counts_per_rev=0, **PLANT))
    a, b = runs
    assert np.max(np.abs(a.omega_l - b.omega_l)) <= 1e-9 * np.max(np.abs(a.omega_l))
    assert np.max(np.abs(a.u - b.u)) <= 1e-7


def test_the_motor_angle_trim_acts_alike_in_the_compiled_law(model):
    """A short reference (tau_ref 0.1 s: the approach is over at 0.6 s) and a fast trim (1/s): the law's target moves
    within the run (at 5 rad/s; 3 rad/s is not near its target by then), in the compiled law as in ``act``."""
    ref, runs = np.array([3.0, 5.0]), {}
    for compiled, gain in ((False, 1.0), (True, 1.0), (False, 0.0)):
        c = controllers.make("observer", config="torsional", omega_ref=ref, model=model, tau_ref=0.1, angle_gain=gain)
        runs[compiled, gain] = run_closed_loop(c, "torsional", ref, 3.0, compiled=compiled, counts_per_rev=0, **PLANT)
        if not compiled and gain:
            assert c._integrating.any() and np.any(c.law.target != ref)  # the trim started and moved the target
    a, b, off = runs[False, 1.0], runs[True, 1.0], runs[False, 0.0]
    assert np.max(np.abs(a.u[1] - off.u[1])) > 1e-3  # the trim changes the commands
    # the trimmed lane over 3 s (round-off grows along a closed loop: the 3 rad/s lane, stuck and freed, to 3e-5)
    assert np.max(np.abs(a.omega_l[1] - b.omega_l[1])) <= 1e-7 * np.max(np.abs(a.omega_l[1]))
    assert np.max(np.abs(a.u[1] - b.u[1])) <= 1e-6


def test_a_user_file_effect_reaches_the_compiled_law():
    """A Force from a user file (a cubic string) changes the compiled law's commands as it changes ``act``'s."""
    from controllers.compiled import model_law

    spec = ("examples/effects/string_cubic.py:string_cubic",)
    m = {"theta_u": np.zeros(2), "omega_ref": np.array([2.0, 4.0])}
    u = {}
    for c3 in (0.0, 0.2):
        mdl = Model(RigParams(), spec, {"c3": c3})
        c = controllers.make("observer", config="torsional", omega_ref=m["omega_ref"], model=mdl)
        c.reset(m)
        c.observer.x[2] = 0.5  # a wound string (rad): the cubic term acts
        law = c.compiled_law()
        assert law.step is model_law.law_step(mdl.composition, "observer")  # compiled once per composition
        M, U = np.zeros((5, 2)), np.zeros(2)
        law.step(0.0, M, law.state.copy(), law.constants, U)
        np.testing.assert_allclose(U, c.act(m), rtol=0, atol=1e-12)
        u[c3] = U.copy()
    assert np.max(np.abs(u[0.2] - u[0.0])) > 1e-4


def test_a_measurement_on_the_motor_angle_keeps_the_step_by_step_loop(tmp_path):
    (tmp_path / "scale.py").write_text(SCALE_FILE)
    model = Model(RigParams(), (f"{tmp_path / 'scale.py'}:encoder_scale",), {"enc_scale": 0.02})
    c = controllers.make("observer", config="torsional", omega_ref=[3.0], model=model)
    c.reset({"theta_u": np.zeros(1), "omega_ref": np.array([3.0])})
    assert c.compiled_law() is None


def test_a_subclass_with_its_own_act_has_no_compiled_law():
    c = controllers.make("observer-robust", config="torsional", omega_ref=[3.0])
    assert c.compiled_law() is None  # its act is not the observer's


def test_the_law_follows_the_brake_laws_dependence_on_the_lower_angle():
    """With position friction the brake torque T(w, theta_l) the law inverts has derivatives in the lower angle
    (analytic: Tfl(w) (-c1 sin + s1 cos) and -Tfl(w) (c1 cos + s1 sin) at theta_l); the compiled law reads them from
    six more torque rows and gives ``act``'s command."""
    from drillgym.closed_loop.abi import M_REF, M_TU

    c1, s1, th = 0.15, 0.1, 0.3
    ref = np.array([2.0, 3.0])
    mdl = Model(RigParams(), ("position_friction",), {"pf_c1": c1, "pf_s1": s1})
    c = controllers.make("observer", config="torsional", omega_ref=ref, model=mdl)
    c.reset({"theta_u": np.full(2, th)})
    c.observer.x[0], c.observer.x[2], c.observer.x[3] = th, 0.0, ref  # no twist: theta_l = theta_u; slipping
    T, T1, _, Ta, Taa, Twa = c.law.friction(ref, np.zeros(2))
    level = 1 + c1 * np.cos(th) + s1 * np.sin(th)
    slope = -c1 * np.sin(th) + s1 * np.cos(th)
    np.testing.assert_allclose(Ta, T / level * slope, rtol=1e-5)
    np.testing.assert_allclose(Taa, -T / level * (level - 1), rtol=1e-4)
    np.testing.assert_allclose(Twa, T1 / level * slope, rtol=1e-3)
    law = c.compiled_law()
    M, U = np.zeros((5, 2)), np.zeros(2)
    M[M_TU], M[M_REF] = th, ref
    law.step(0.0, M, law.state.copy(), law.constants, U)
    np.testing.assert_allclose(U, c.act({"theta_u": np.full(2, th), "omega_ref": ref}), rtol=0, atol=1e-12)
