"""The controller interface, the registry and the agent hook."""

import numpy as np
import pytest

import controllers
from controllers.base import Controller
from controllers.baseline import BaselineController, stick_slip_region
from drillgym.equilibria import slip_equilibria


def test_registry_names_and_errors():
    assert controllers.available() == [
        "baseline",
        "descent",
        "lqg",
        "lqg-2enc",
        "observer",
        "observer-robust",
        "pi",
        "softtorque",
    ]
    with pytest.raises(ValueError, match="unknown controller 'pid'"):
        controllers.make("pid", omega_ref=1.0)
    with pytest.raises(ValueError, match="omega_ref"):
        controllers.make("pi", omega_ref=-1.0)
    with pytest.raises(ValueError, match="lower disc"):
        controllers.make("pi", config="upper", omega_ref=1.0)
    assert controllers.make("observer@10", omega_ref=1.0).dt == 0.01  # NAME@MS: another control period
    assert controllers.make("pi@2", omega_ref=1.0).dt == 0.002 and controllers.make("pi", omega_ref=1.0).dt == 0.01
    with pytest.raises(ValueError, match="in ms"):
        controllers.make("observer@fast", omega_ref=1.0)
    with pytest.raises(ValueError, match="positive"):
        controllers.make("observer@0", omega_ref=1.0)
    with pytest.raises(ValueError, match="10 ms from the name but dt=0.002"):
        controllers.make("observer@10", omega_ref=1.0, dt=0.002)


def test_scalar_and_batched_use():
    c = controllers.make("pi", omega_ref=2.0)
    with pytest.raises(RuntimeError, match="reset"):
        c.act({"theta_u": 0.0})
    c.reset({"t": 0.0, "theta_u": 0.0})
    u = c({"t": 0.0, "theta_u": 0.0})
    assert isinstance(u, float) and 0 < u <= 5.0
    with pytest.raises(ValueError, match="theta_u"):
        c.act({"t": 0.01})
    c.reset({"theta_u": np.zeros(3), "omega_ref": np.array([0.2, 0.5, 0.8])})
    u = c.act({"theta_u": np.zeros(3)})
    assert u.shape == (3,) and np.all(np.diff(u) > 0)  # faster targets, more voltage


def test_baseline_voltage_holds_the_target_equilibrium():
    c = BaselineController(omega_ref=7.0)
    c.reset()
    u = c.act({})
    speeds = [e.omega for e in slip_equilibria("torsional", u) if e.stable]
    assert max(speeds) == pytest.approx(7.0, rel=1e-6)


def test_stick_slip_region_from_the_bifurcation_analysis():
    reg = stick_slip_region("torsional")
    assert reg.omega_lo == pytest.approx(0.0608, abs=2e-3)  # first Hopf point (R2/R3)
    assert 6.2 < reg.omega_hi < 7.0 and 3.75 <= reg.u_fold <= 3.95  # second fold (R7)
    c = BaselineController(omega_ref=3.0)
    c.reset()
    assert "stick-slip region" in c.regime()
    assert "reached from rest" in c.regime(7.5)


def test_agent_hook():
    class Const(Controller):
        name = "const"

        def _act(self, m):
            return np.full(self.n, 1.5)

    seen = {}

    def loader(path, **kw):
        seen.update(kw, path=path)
        return Const(kw["omega_ref"], config=kw["config"])

    controllers.register_agent_loader(loader)
    try:
        c = controllers.make("agent:/tmp/model.zip", config="coupled", omega_ref=2.0)
        c.reset()
        assert c.act({}) == 1.5 and seen["path"] == "/tmp/model.zip" and seen["config"] == "coupled"
    finally:
        controllers.registry._agent_loader = None
    with pytest.raises(ValueError, match="agent:PATH"):
        controllers.make("agent:")


def test_reset_rigs_checks_before_restarting_and_refuses_what_it_cannot_restart():
    pi = controllers.make("pi", omega_ref=2.0)
    with pytest.raises(ValueError, match="reset\\(\\) the batch before"):
        pi.reset_rigs(np.array([0]), {"theta_u": np.zeros(2)})
    pi.reset({"theta_u": np.zeros(2), "omega_u": np.zeros(2), "omega_ref": np.array([2.0, 3.0])})
    with pytest.raises(NotImplementedError, match="cannot restart single rigs"):
        pi.reset_rigs(np.array([0]), {"theta_u": np.zeros(2)})
    obs = controllers.make("observer", omega_ref=2.0)
    obs.reset({"theta_u": np.zeros(2), "omega_ref": np.array([2.0, 3.0])})
    with pytest.raises(ValueError, match="positive finite"):
        obs.reset_rigs(np.array([1]), {"theta_u": np.zeros(2), "omega_ref": np.array([2.0, -1.0])})
    assert np.array_equal(obs.omega_ref, [2.0, 3.0])  # a refused restart changes nothing
    obs.u_prev[:] = 1.0
    obs.reset_rigs(np.array([1]), {"theta_u": np.zeros(2), "omega_ref": np.array([9.0, 4.0])})
    assert np.array_equal(obs.omega_ref, [2.0, 4.0]) and np.array_equal(obs.u_prev, [1.0, 0.0])


def test_a_subclass_that_changes_the_law_keeps_no_compiled_law_of_its_parent():
    """A compiled law runs in place of ``act`` only when it was written beside the ``_act`` the controller runs:
    a subclass that changes ``_act`` gets none (the parent's would compute the parent's commands), one that
    changes nothing keeps it, one that compiles its own offers that."""
    from controllers.pi import PIController

    class Changed(PIController):
        def _act(self, m):
            return super()._act(m) + 0.1

    class Same(PIController):
        pass

    class Recompiled(Changed):
        def _compiled_law(self):
            return "own"

    m = {"theta_u": np.zeros(1), "omega_ref": np.array([3.0])}
    laws = {}
    for cls in (Changed, Same, Recompiled):
        c = cls(config="torsional", omega_ref=np.array([3.0]))
        c.reset(m)
        laws[cls.__name__] = c.compiled_law()
    assert laws["Changed"] is None and laws["Recompiled"] == "own", laws
    assert laws["Same"] is not None and laws["Same"] != "own", laws


def test_softtorque_runs_its_own_law_not_the_compiled_pi_of_its_parent():
    """SoftTorqueController inherits the PI loop but not its compiled law (which would run the plain PI): the
    harness's default run is its step-by-step reference, which holds 3 rad/s where the PI stick-slips."""
    from controllers.evaluation.metrics import run_metrics
    from controllers.evaluation.runner import run_closed_loop

    ref = np.array([3.0])
    c = controllers.make("softtorque", config="coupled", omega_ref=ref)
    assert c.compiled_law() is None
    ssi = run_metrics(run_closed_loop(c, "coupled", ref, 30.0), 10.0)["ssi"]
    assert ssi[0] < 0.1, ssi


def test_the_scores_limits_are_the_rigs_safety_limits():
    """The evaluation judges runs against the rig's own stops (over-speed, lateral over-displacement), which
    the hardware's safety layer defines: the two must not drift apart."""
    from controllers.evaluation.metrics import LATERAL_STOP, SAFETY_SPEED
    from hw.safety import SafetyLimits

    limits = SafetyLimits()
    assert (SAFETY_SPEED, LATERAL_STOP) == (limits.max_speed, limits.max_displacement)
