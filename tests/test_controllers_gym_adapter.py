"""A Controller drives the Gymnasium env through ControllerPolicy (measurements from the observation)."""

import gymnasium as gym
import numpy as np
import pytest

import controllers
import drillgym.envs  # noqa: F401  (registers the ids)
from controllers.gym_adapter import ControllerPolicy, run_episode


@pytest.mark.parametrize("mode", ["sensors", "motor"])
def test_observer_episode_in_the_torsional_env(mode):
    env = gym.make(
        "drillgym/Torsional-v0", observation=mode, omega_ref=2.0, alpha0_range=(0.0, 0.0), episode_duration=40.0
    )
    res = {
        name: run_episode(controllers.make(name, omega_ref=2.0, dt=0.01), env, seed=0)
        for name in ("baseline", "observer")
    }
    assert len(res["observer"]["t"]) == 4000 and res["observer"]["t"][-1] == pytest.approx(40.0)
    ss = slice(-1500, None)
    base, obs = res["baseline"]["omega_l"][ss], res["observer"]["omega_l"][ss]
    assert base.min() == 0.0  # open loop: stick-slip at 2 rad/s
    assert np.all(np.abs(obs - 2.0) < 0.05)  # observer from the motor angle alone: held
    assert np.all(np.abs(res["observer"]["u"]) <= 5.0)
    assert res["observer"]["reward"].sum() > res["baseline"]["reward"].sum()


def test_policy_unwraps_angles_and_scales_actions():
    env = gym.make(
        "drillgym/Torsional-v0", observation="sensors", omega_ref=8.0, normalize_action=True, alpha0_range=(0.0, 0.0)
    )
    pol = ControllerPolicy(controllers.make("baseline", omega_ref=8.0), env)
    obs, _ = env.reset(seed=1)
    pol.reset(obs)
    for _ in range(300):
        a = pol(obs)
        assert a.shape == (1,) and -1.0 <= a[0] <= 1.0
        obs, *_ = env.step(a)
    m = pol.measurement(obs)  # the next measurement: the angle after 300 periods
    assert m["theta_u"] > 2 * np.pi  # several turns: unwrapped, not the wrapped reading
    assert m["omega_ref"] == 8.0


def test_policy_refuses_what_it_cannot_serve():
    with pytest.raises(ValueError, match="observation='sensors' or 'motor'"):
        ControllerPolicy(controllers.make("pi", omega_ref=1.0), gym.make("drillgym/Torsional-v0", observation="full"))
    with pytest.raises(ValueError, match="control_dt"):
        ControllerPolicy(
            controllers.make("pi", omega_ref=1.0, dt=0.02), gym.make("drillgym/Torsional-v0", observation="sensors")
        )
