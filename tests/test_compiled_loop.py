"""The compiled closed loop against the step-by-step reference (controllers.evaluation.runner.run_closed_loop).

Tolerances:

* ``pi``, ``descent``: the same runs bit for bit (the same plant kernels, measurement arithmetic and noise stream);
* ``observer``: one period of the compiled law from the reference controller's state agrees with ``act`` to
  1e-12 (V, and relative on the estimates) with quantized angles; whole runs with exact angles agree to 1e-8
  relative on omega_l and 1e-5 V on u over 2 s.  Longer runs part: the closed loop amplifies round-off (the reference
  against itself with its covariance scaled by 1 + 1e-15 differs by 1e-3 rad/s after 2 s).
* ``lqg``, ``lqg-2enc``: the same tolerances as ``observer`` (their laws use the vectorisable exp and log of the
  brake law, and sum their matrix products in another order than numpy).

The plant runs a library effect (``motor_lag``) the controllers do not know.
"""

import numpy as np
import pytest

import controllers
from controllers.evaluation.runner import run_closed_loop
from drillgym.errors import InputError

SIGNALS = ("u", "omega_u", "omega_l", "alpha", "stuck_l", "friction_l", "r")
PLANT = {"effects": ["motor_lag"]}


def _runs(name, ref, duration, plant=PLANT, **kw):
    out = []
    for compiled in (False, True):
        c = controllers.make(name, config="torsional", omega_ref=ref)
        out.append(run_closed_loop(c, "torsional", ref, duration, compiled=compiled, **plant, **kw))
    return out


# the scalar kernel (< 8 runs), the lane kernel with padded lanes; with a lag each lane starts its periods on the
# scalar path, without one the lanes restart in place (stuck discs resolved on the scalar path)
@pytest.mark.parametrize("n, plant", [(3, PLANT), (10, PLANT), (10, {}), (16, {})])
def test_pi_compiled_loop_is_the_reference_to_round_off(n, plant):
    """The same runs to round-off: two separately compiled kernels may contract a multiply-add differently (a
    fresh compile differed from the reference in 10 of 1000 samples by one unit in the last place)."""
    ref = np.linspace(1.0, 6.0, n)
    a, b = _runs("pi", ref, 1.0, plant, angle_noise=2e-4, seed=5)
    np.testing.assert_array_equal(a.t, b.t)
    for k in SIGNALS:
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-12, atol=1e-12, err_msg=k)


@pytest.mark.parametrize("ramp", [0.5, 0.0])
def test_descent_compiled_loop_is_the_reference_to_round_off(ramp):
    """Approach, ramp and integral hold (short: a 0.3 s hold), a target above the approach's held from the start;
    the same runs to round-off, the integral's start at the same period."""
    ref = np.array([1.0, 2.5, 4.0, 30.0])
    runs = []
    for compiled in (False, True):
        c = controllers.make("descent", config="torsional", omega_ref=ref, hold=0.3, ramp=ramp, ki=0.5)
        runs.append(run_closed_loop(c, "torsional", ref, 1.2, compiled=compiled, angle_noise=2e-4, seed=5, **PLANT))
    a, b = runs
    assert np.ptp(a.u[0]) > 1.0  # the voltage ramps down
    for k in SIGNALS:
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=1e-12, atol=1e-12, err_msg=k)


def test_observer_law_one_period_matches_act_along_a_reference_run():
    """The command and estimates to 1e-12, the covariance (the update, the Jacobian at the estimates, the
    prediction) to 1e-10 of each lane's largest entry (numpy sums the matrix products in another order)."""
    from controllers.compiled.observer_law import _P0, observer_law

    n = 6
    ref = np.linspace(1.0, 6.0, n)
    c0 = controllers.make("observer", config="torsional", omega_ref=ref)
    angles = []
    act = c0.act
    c0.act = lambda m: (angles.append(np.array(m["theta_u"])), act(m))[1]
    run_closed_loop(c0, "torsional", ref, 0.6, compiled=False, **PLANT)  # quantized angles, 8000 counts/rev
    c = controllers.make("observer", config="torsional", omega_ref=ref)
    c.reset({"theta_u": angles[0], "omega_ref": ref})
    M, U = np.zeros((5, n)), np.zeros(n)
    M[4] = ref
    for k, th in enumerate(angles):
        law = observer_law(c)
        X = law.state.copy()
        M[0] = th
        u = c.act({"theta_u": th})
        law.step(k * c.dt, M, X, law.constants, U)
        assert np.max(np.abs(U - u)) <= 1e-12
        x = c.observer.x
        assert np.all(np.abs(X[:5] - x) <= 1e-12 * (1.0 + np.abs(x)))
        P = c.observer.P.reshape(n, 25).T
        assert np.all(np.abs(X[_P0 : _P0 + 25] - P) <= 1e-10 * np.abs(P).max(axis=0))


def _estimates(name, c):
    """The reference controller's estimates (rows, n), held in the first rows of its compiled law's state."""
    return {"observer": lambda: c.observer.x, "lqg": lambda: c._x, "lqg-2enc": lambda: c.x.T}[name]()


def assert_laws_match_act(name, ref, duration, plant, **kw):
    """One period of the compiled law from the controller's state before each ``act`` of a reference run of
    ``duration`` s (quantized angles, 8000 counts/rev) agrees with it: to 1e-12 V, 1e-12 relative on the estimates;
    ``kw`` the controller's options."""
    c0 = controllers.make(name, config="torsional", omega_ref=ref, **kw)
    ms = []
    act = c0.act
    c0.act = lambda m: (ms.append({k: np.array(v) for k, v in m.items()}), act(m))[1]
    run_closed_loop(c0, "torsional", ref, duration, compiled=False, **plant)
    c = controllers.make(name, config="torsional", omega_ref=ref, **kw)
    c.reset(ms[0])
    M, U = np.zeros((5, ref.size)), np.zeros(ref.size)
    M[4] = ref
    for k, m in enumerate(ms):
        law = c.compiled_law()
        X = law.state.copy()
        M[0], M[1] = m["theta_u"], m["theta_l"]
        u = c.act(m)
        law.step(k * c.dt, M, X, law.constants, U)
        assert np.max(np.abs(U - u)) <= 1e-12
        x = _estimates(name, c)
        assert np.all(np.abs(X[: x.shape[0]] - x) <= 1e-12 * (1.0 + np.abs(x)))


@pytest.mark.parametrize("name", ["lqg", "lqg-2enc"])
def test_lqg_laws_one_period_match_act_along_a_reference_run(name):
    assert_laws_match_act(name, np.linspace(1.0, 6.0, 6), 0.6, PLANT)


@pytest.mark.parametrize("name", ["lqg", "lqg-2enc"])
def test_lqg_compiled_runs_match_the_reference_with_exact_angles(name):
    ref = np.array([1.0, 2.0, 3.0, 4.5, 6.0, 7.0, 2.5, 5.0])
    a, b = _runs(name, ref, 2.0, counts_per_rev=0)
    scale = np.max(np.abs(a.omega_l))
    assert np.max(np.abs(a.omega_l - b.omega_l)) <= 1e-8 * scale
    assert np.max(np.abs(a.u - b.u)) <= 1e-5


def test_observer_compiled_run_matches_the_reference_with_exact_angles():
    ref = np.array([1.0, 2.0, 3.0, 4.5, 6.0, 7.0, 2.5, 5.0])
    a, b = _runs("observer", ref, 2.0, counts_per_rev=0)
    scale = np.max(np.abs(a.omega_l))
    assert np.max(np.abs(a.omega_l - b.omega_l)) <= 1e-8 * scale
    assert np.max(np.abs(a.u - b.u)) <= 1e-5  # V: the law differentiates the estimates twice


def test_a_controller_without_a_law_keeps_the_step_by_step_loop():
    ref = np.array([2.0, 3.0])
    c = controllers.make("baseline", config="torsional", omega_ref=ref)
    assert c.compiled_law() is None
    run = run_closed_loop(c, "torsional", ref, 0.1, **PLANT)  # compiled=None: no error
    assert run.u.shape == (2, int(round(0.1 / c.dt)))
    with pytest.raises(InputError, match="no compiled law"):
        run_closed_loop(controllers.make("baseline", config="torsional", omega_ref=ref), "torsional", ref, 0.1,
                        compiled=True)  # fmt: skip


@pytest.mark.parametrize("n", [3, 16])  # the scalar kernel and the lane kernel
def test_a_law_that_gives_a_non_finite_command_stops_the_loop_at_that_period(n):
    """A command that is not finite in one lane at t = 6 ms: FloatingPointError naming that time, the signals of
    the periods before recorded as the law gave them."""
    from numba import njit

    from drillgym import BatchSimulator, Configuration
    from drillgym.closed_loop import run_compiled_loop
    from drillgym.closed_loop.abi import LAW_SIGNATURE

    @njit(LAW_SIGNATURE)
    def law(t, M, X, C, U):  # pragma: no cover - compiled
        for k in range(U.size):
            U[k] = np.nan if (t > 0.005 and k == U.size - 1) else 1.5

    sim = BatchSimulator(Configuration.TORSIONAL, n, dt=1e-3)
    sim.reset()
    zeros = np.zeros(n)
    first = {"theta_u": zeros, "theta_l": zeros, "x": zeros, "y": zeros, "omega_ref": np.ones(n)}
    with pytest.raises(FloatingPointError, match="t = 0.006 s"):
        run_compiled_loop(sim, law, np.zeros((1, n)), np.zeros(1), periods=10, control_dt=0.002, first=first,
                          counts_per_rev=np.full(n, 8000.0), angle_noise=zeros, rng=np.random.default_rng(0),
                          u_max=10.0)  # fmt: skip
    assert np.all(sim.Y[:, 2] > 0.0) and np.all(np.isfinite(sim.Y))  # three periods at 1.5 V, none at NaN
