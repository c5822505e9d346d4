"""An episode whose state stops being finite ends there: terminated, with the reason in ``info``.

A user effect whose torque turns NaN once the upper disc spins faster than ``w_nan`` (finite at the
validation's typical states with its default, so the file is accepted) breaks the rigs driven at
5 V and leaves the rig at 0 V alone. Observation, reward and info stay finite (the last finite
ones); the vector env terminates and autoresets only the broken rigs.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from drillgym.envs import make_vec

EFFECT = """
import math

from drillgym.effects import Force, Parameter


class NanAbove(Force):
    name = "nan_above"
    acts_on = "lower"
    parameters = (
        Parameter("w_nan", unit="rad/s", lo=0.0, hi=1000.0, guess=500.0, scale=1.0, doc="speed of the NaN"),
    )
    explanation = "a broken formula: NaN above a speed of the upper disc"
    signature = "none"

    def torque(omega_u, w_nan):
        if abs(omega_u) < w_nan:
            return 0.0
        return math.nan
"""
W_NAN = 0.5  # rad/s: reached within a few periods at 5 V, never at 0 V


@pytest.fixture(scope="module")
def effect(tmp_path_factory) -> dict:
    path = tmp_path_factory.mktemp("effects") / "nan_above.py"
    path.write_text(EFFECT, encoding="utf-8")
    return {"effects": [f"{path}:nan_above"], "effect_params": {"w_nan": W_NAN}}


def _run_until_terminated(env, volts: float, steps: int = 200):
    obs, _ = env.reset(seed=0)
    for i in range(steps):
        prev = obs
        obs, reward, terminated, truncated, info = env.step(np.array([volts / 5.0], dtype=np.float32))
        if terminated or truncated:
            return i, prev, obs, reward, terminated, truncated, info
        assert "termination" not in info
    raise AssertionError(f"not terminated in {steps} steps")


@pytest.mark.parametrize("observation", ["full", "sensors"])
def test_single_env_terminates_with_the_reason_and_finite_values(effect: dict, observation: str) -> None:
    env = gym.make("drillgym/Torsional-v0", observation=observation, omega_ref=4.0, **effect)
    i, prev, obs, reward, terminated, truncated, info = _run_until_terminated(env, 5.0)
    assert terminated and not truncated and i < 100
    assert np.isfinite(obs).all() and np.isfinite(reward)
    np.testing.assert_array_equal(obs, prev)  # the last finite observation
    assert all(np.isfinite(v) for k, v in info.items() if k != "termination")
    reason = info["termination"]
    assert reason.startswith("non-finite state: ") and "omega_u = nan" in reason
    assert f"t = {info['time']:.6g} s" in reason
    assert not np.isfinite(env.unwrapped.batch.system.Y[0]).all()  # it really was the state
    obs, info = env.reset(seed=1)  # a new episode starts clean
    assert np.isfinite(obs).all() and "termination" not in info
    obs, reward, terminated, *_ = env.step(np.array([0.0], dtype=np.float32))
    assert not terminated and np.isfinite(reward)


def test_over_speed_names_the_speed_and_the_limit() -> None:
    env = gym.make("drillgym/Torsional-v0", max_speed=1.0, omega_ref=0.5)
    *_, info = _run_until_terminated(env, 5.0)
    assert info["termination"].startswith("over-speed: omega_u = ")
    assert "beyond max_speed = 1 rad/s" in info["termination"]


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_vector_env_terminates_only_the_broken_rigs(effect: dict, mode: str) -> None:
    venv = make_vec("drillgym/Torsional-v0", 3, autoreset_mode=mode, omega_ref=4.0, **effect)
    venv.reset(seed=0)
    volts = np.array([1.0, 0.0, 1.0])  # normalised: 5 V, 0 V, 5 V
    for _ in range(100):
        obs, reward, terminated, truncated, info = venv.step(volts)
        assert np.isfinite(obs).all() and np.isfinite(reward).all()
        if terminated.any():
            break
    assert terminated.tolist() == [True, False, True]
    if mode == "NextStep":
        assert info["_termination"].tolist() == [True, False, True]
        assert info["termination"][0].startswith("non-finite state: ") and info["termination"][1] == ""
        obs, reward, terminated, truncated, info = venv.step(volts)  # the broken rigs start again
        assert reward[[0, 2]].tolist() == [0.0, 0.0] and not terminated.any()
        assert info["time"][[0, 2]].tolist() == [0.0, 0.0] and info["time"][1] > 0.0
    else:
        final = info["final_info"]
        assert info["_final_info"].tolist() == [True, False, True]
        assert final["termination"][2].startswith("non-finite state: ")
        assert np.isfinite(np.stack(info["final_obs"][[0, 2]])).all()
        assert "termination" not in info  # the rigs were reset within the step
    assert np.isfinite(obs).all()
    assert np.isfinite(venv.batch.system.Y).all()


def test_sb3_adapter_passes_the_reason_on(effect: dict) -> None:
    pytest.importorskip("stable_baselines3")
    from drillgym.envs.sb3 import make_sb3_vec

    venv = make_sb3_vec("drillgym/Torsional-v0", 2, omega_ref=4.0, **effect)
    venv.reset()
    for _ in range(100):
        venv.step_async(np.array([[1.0], [0.0]]))
        obs, reward, dones, infos = venv.step_wait()
        if dones.any():
            break
    assert dones.tolist() == [True, False]
    assert infos[0]["termination"].startswith("non-finite state: ") and "termination" not in infos[1]
    assert np.isfinite(infos[0]["terminal_observation"]).all() and np.isfinite(obs).all()
