"""DAgger from the motor-encoder observer run in shadow: labels from the 'motor' observation, per-rig restart."""

from __future__ import annotations

import numpy as np
import pytest

import drillgym  # noqa: F401
from drillgym.errors import InputError


def test_shadow_observer_labels_are_what_the_observer_outputs_on_the_motor_increments() -> None:
    import gymnasium as gym

    import controllers
    from agents.teachers import ShadowTeacher
    from controllers.gym_adapter import ControllerPolicy

    env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=1.5, normalize_action=True)
    policy = ControllerPolicy(controllers.make("observer", dt=0.01), env)
    obs, _ = env.reset(seed=3)
    policy.reset(obs)
    names = env.unwrapped.observation_names
    teacher = ShadowTeacher("observer", 1, 0.01, names)
    target = np.array([1.5])
    teacher.reset([0], obs[None, :], target)
    Y = env.unwrapped.batch.system.Y
    start = float(Y[0, 0])
    for _ in range(300):  # 3 s
        a = policy(obs)
        label = teacher.act(obs[None, :], target)
        assert abs(float(label[0]) - float(a[0])) < 1e-5
        teacher.applied(a)
        obs, *_ = env.step(a)
    moved = float(Y[0, 0]) - start  # the true motor angle's change (rad): the increments' sum, within counts
    assert moved > 3.0 and abs(teacher.theta[0, 0] - moved) < 0.005  # a few counts of 2 pi / 8000
    with pytest.raises(InputError, match="has no theta_l"):
        ShadowTeacher("lqg-2enc", 1, 0.01, names)


def test_observer_restarts_one_rig_alone_and_predicts_with_the_applied_voltage() -> None:
    from controllers.observer import ObserverController

    both, alone, fresh = ObserverController(dt=0.01), ObserverController(dt=0.01), ObserverController(dt=0.01)
    ref = np.array([1.5, 3.0])
    both.reset({"theta_u": np.zeros(2), "omega_ref": ref})
    alone.reset({"theta_u": np.zeros(1), "omega_ref": ref[:1]})
    for k in range(50):
        m = {"theta_u": 0.02 * k + np.array([0.0, 1e-3 * k]), "omega_ref": ref}
        both.act(m)
        alone.act({n: v[:1] for n, v in m.items()})
    m1 = {"theta_u": np.array([0.0, 7.0]), "omega_ref": np.array([1.5, 1.0])}
    both.reset_rigs(np.array([1]), m1)
    fresh.reset({k: v[1:] for k, v in m1.items()})
    for k in range(50):  # (n = 1 or 2 batched products: equal within rounding)
        m = {"theta_u": np.array([1.0, 7.0]) + 0.01 * k, "omega_ref": ref}
        u = both.act(m)
        assert u[0] == pytest.approx(float(alone.act({n: v[:1] for n, v in m.items()})[0]), rel=1e-6)
        assert u[1] == pytest.approx(float(fresh.act({n: v[1:] for n, v in m.items()})[0]), rel=1e-6)
    assert both.omega_ref[1] == 1.0 and both.law.t[1] == pytest.approx(0.5) and both.law.t[0] == pytest.approx(1.0)

    # applied(): the filter's prediction is the one made with the executed voltage, not its own
    own, shadow = ObserverController(dt=0.01), ObserverController(dt=0.01)
    for c in (own, shadow):
        c.reset({"theta_u": np.zeros(2), "omega_ref": ref})
    for k in range(20):
        m = {"theta_u": np.full(2, 0.01 * k), "omega_ref": ref}
        u = own.act(m)
        shadow.act(m)
        shadow.applied(u if k < 10 else u + 1.0)  # its own voltage: the prediction it made (not a second one)
        if k < 10:
            np.testing.assert_allclose(shadow.estimate, own.estimate, rtol=0, atol=1e-12)
    assert np.abs(shadow.estimate[1] - own.estimate[1]).min() > 1e-3  # 1 V more: a faster motor predicted
