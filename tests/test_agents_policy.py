"""The agent as a Controller: same observation as the env, the kept policy in the harness, load errors."""

import json

import gymnasium as gym
import numpy as np
import pytest

import agents
import controllers
import drillgym  # noqa: F401  (registers the envs)
from agents.controller import AgentController
from controllers.evaluation import SCENARIOS, run_job
from drillgym.measurement import quantize_angle

KEPT = str(agents.KEPT_POLICY)
#: the first kept agent (residual on the start-up feedforward, the env's 'motor' observation)
PPO_MOTOR = str(agents.KEPT_POLICY.parents[1] / "torsional_motor_ppo" / "policy.npz")


def test_controller_builds_the_env_observation_and_voltage():
    """Fed the encoder readings of an env, the adapter sees exactly the env's observation and returns
    the residual voltage u_ff(omega_ref, t) + scale * policy(obs) (start-up schedule included)."""
    ctrl = controllers.make(f"agent:{PPO_MOTOR}", config="torsional", omega_ref=3.0)
    assert isinstance(ctrl, AgentController) and ctrl.uses == ("theta_u",)
    opts = ctrl.policy.config["hyperparams"]["env_kwargs"]
    env = gym.make(
        "drillgym/Torsional-v0",
        observation="motor",
        motor_history=opts["motor_history"],
        omega_ref=3.0,
        normalize_action=False,
    ).unwrapped
    obs, _ = env.reset(seed=5)
    system = env.batch.system

    def reading():
        return {"t": 0.0, "theta_u": float(quantize_angle(system.theta_u[0]))}

    ctrl.reset(reading())
    scale = ctrl.policy.config["hyperparams"]["residual"]
    for k in range(400):
        u = ctrl.act(reading())
        np.testing.assert_allclose(ctrl.stack[0], obs, atol=1e-5, err_msg=f"step {k}")
        u_ff = ctrl.residual.feedforward(np.array([3.0]), k * env.options.control_dt)[0]
        expected = np.clip(u_ff + scale * ctrl.policy.act(obs)[0], -5, 5)
        assert u == pytest.approx(expected, abs=1e-5)
        obs, *_ = env.step(np.array([u]))
    assert system.omega_l[0] > 0.5  # the rig turns


def test_kept_policy_beats_the_baseline_at_3_rad_s():
    base, agent = (
        run_job(c, "torsional", SCENARIOS["rest"], [3.0], duration=60.0, window=20.0)[0]
        for c in ("baseline", f"agent:{KEPT}")
    )
    assert base["ssi"] > 1.0  # the open-loop rig sticks and slips
    assert agent["ssi"] < 0.1 < base["ssi"]


@pytest.mark.parametrize("scenario", ["friction-20", "friction+20"])
def test_kept_policy_holds_2_rad_s_with_friction_20_percent_off(scenario):
    """Below the fold (2 rad/s) the open loop sticks and slips; the agent, friction 20 % off its
    training value, holds the target without stick-slip and without running faster than it."""
    base, agent = (
        run_job(c, "torsional", SCENARIOS[scenario], [2.0], duration=60.0, window=20.0)[0]
        for c in ("baseline", f"agent:{KEPT}")
    )
    assert base["ssi"] > 1.0
    assert agent["ssi"] < 0.1 and agent["tracking_rms"] < 0.1


def test_kept_policy_is_small_and_recorded():
    folder = agents.KEPT_POLICY.parent
    assert sum(f.stat().st_size for f in folder.iterdir()) < 500_000
    cfg = agents.load_policy(KEPT).config
    assert cfg["command"].startswith("drillgym train") and f"--seed {cfg['seed']}" in cfg["command"]
    assert cfg["command"] in (folder / "README.md").read_text()


def test_load_errors_name_the_problem(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        controllers.make(f"agent:{tmp_path / 'missing.npz'}")
    bad = tmp_path / "bad.npz"
    np.savez(bad, x=np.zeros(3))
    with pytest.raises(ValueError, match="not an exported drillgym policy"):
        agents.load_policy(bad)
    with pytest.raises(ValueError, match=r"\(.npz\) or an SB3 model"):
        (tmp_path / "p.txt").write_text("x")
        agents.load_policy(tmp_path / "p.txt")
    # an agent trained on the true state cannot run on measurements
    with np.load(PPO_MOTOR) as z:
        arrays = dict(z)
    meta = json.loads(str(arrays["meta"]))
    meta["config"]["hyperparams"]["env_kwargs"]["observation"] = "full"
    arrays["meta"] = np.array(json.dumps(meta))
    full = tmp_path / "full.npz"
    np.savez(full, **arrays)
    with pytest.raises(ValueError, match="'full' observation"):
        agents.load_controller(str(full), config="torsional", omega_ref=3.0)


ROBUST = str(agents.KEPT_POLICY.parents[1] / "torsional_motor_learned_robust" / "policy.npz")


@pytest.mark.parametrize("scenario", ["friction-20", "friction+20"])
def test_robust_learned_policy_holds_3_5_rad_s_from_rest_with_friction_20_percent_off(scenario):
    """The population-trained motor-side policy (speed command from above, agents/command.py): from rest,
    where the open loop sticks and slips at 3.5 rad/s, it holds the target with the brake 20 % off."""
    base, agent = (
        run_job(c, "torsional", SCENARIOS[scenario], [3.5], duration=60.0, window=20.0)[0]
        for c in ("baseline", f"agent:{ROBUST}")
    )
    assert base["ssi"] > 1.0
    assert agent["ssi"] < 0.1 and agent["tracking_rms"] < 0.1
    assert (
        3.15 < agent["omega_l_min"] and agent["omega_l_max"] < 3.85
    )  # within 10 % of the target throughout the window
