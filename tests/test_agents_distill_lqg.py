"""DAgger from lqg-2enc run in shadow: the teacher's labels, its per-rig restart, the student's observation."""

from __future__ import annotations

import numpy as np
import pytest

import drillgym  # noqa: F401
from agents.envs import MotorIntegralVecEnv, episode_batch
from drillgym.envs.sb3 import make_sb3_vec

SCHEDULE = {"approach": 3.0, "hold": 0.05, "ramp": 0.1, "lag": 0.05, "order": 1}


def _sensors_env(n: int, **kw):
    opts = dict(observation="sensors", omega_ref=3.0, episode_duration=0.5, normalize_action=True)
    return make_sb3_vec("drillgym/Torsional-v0", n, **{**opts, **kw})


def test_shadow_teacher_labels_are_what_lqg_2enc_outputs_on_the_same_readings() -> None:
    import gymnasium as gym

    import controllers
    from agents.teachers import ShadowTeacher
    from controllers.gym_adapter import ControllerPolicy

    env = gym.make("drillgym/Torsional-v0", observation="sensors", omega_ref=2.0, normalize_action=True)
    policy = ControllerPolicy(controllers.make("lqg-2enc", dt=0.01), env)
    obs, _ = env.reset(seed=3)
    policy.reset(obs)
    teacher = ShadowTeacher("lqg-2enc", 1, 0.01, env.unwrapped.observation_names)
    target = np.array([2.0])
    teacher.reset([0], obs[None, :], target)
    for _ in range(300):  # across a wrap of the encoder angles (3 s at up to 3 rad/s)
        a = policy(obs)
        label = teacher.act(obs[None, :], target)
        assert abs(float(label[0]) - float(a[0])) < 1e-6
        teacher.applied(a)
        obs, *_ = env.step(a)
    assert abs(teacher.theta[0, 0]) > np.pi  # unwrapped
    with pytest.raises(ValueError, match="shadow teacher"):
        ShadowTeacher("lqg", 1, 0.01, env.unwrapped.observation_names)


def test_per_rig_reset_restarts_only_that_rigs_filter_and_the_applied_voltage_is_predicted() -> None:
    from controllers.two_encoder import TwoEncoderLQG

    rng = np.random.default_rng(0)
    both, alone, fresh = TwoEncoderLQG(dt=0.01), TwoEncoderLQG(dt=0.01), TwoEncoderLQG(dt=0.01)
    ref = np.array([2.0, 5.0])
    m = {"theta_u": np.zeros(2), "theta_l": np.zeros(2), "omega_ref": ref}
    both.reset(m)
    alone.reset({k: v[:1] for k, v in m.items()})
    for k in range(50):
        m = {
            "theta_u": 0.02 * k + 1e-3 * rng.standard_normal(2),
            "theta_l": 0.02 * k - 0.3 + np.zeros(2),
            "omega_ref": ref,
        }
        both.act(m)
        alone.act({n: v[:1] for n, v in m.items()})
    m1 = {"theta_u": np.array([0.0, 7.0]), "theta_l": np.array([0.0, 6.5]), "omega_ref": np.array([2.0, 1.0])}
    both.reset_rigs(np.array([1]), m1)
    fresh.reset({k: v[1:] for k, v in m1.items()})
    for k in range(50):
        m = {"theta_u": np.array([1.0, 7.0]) + 0.01 * k, "theta_l": np.array([0.7, 6.5]) + 0.01 * k, "omega_ref": ref}
        u = both.act(m)
        assert u[0] == pytest.approx(float(alone.act({n: v[:1] for n, v in m.items()})[0]), abs=1e-12)
        assert u[1] == pytest.approx(float(fresh.act({n: v[1:] for n, v in m.items()})[0]), abs=1e-12)
    assert both.omega_ref[1] == 1.0 and both.t[1] == pytest.approx(0.5) and both.t[0] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="above the designs' grid"):
        both.reset_rigs(np.array([0]), {**m1, "omega_ref": np.array([20.0, 1.0])})

    # in shadow, the estimate predicts the rig driven by another voltage (its own would mislead it)
    venv = _sensors_env(2, counts_per_rev=0, alpha0_range=(0.0, 0.0), episode_duration=5.0)
    venv.seed(0)
    obs = venv.reset()
    s = episode_batch(venv).system
    est = {True: TwoEncoderLQG(dt=0.01), False: TwoEncoderLQG(dt=0.01)}
    for c in est.values():
        c.reset({"theta_u": s.Y[:, 0].copy(), "theta_l": s.Y[:, 1].copy(), "omega_ref": np.full(2, 3.0)})
    err = {True: [], False: []}
    for _ in range(300):
        for shadow, c in est.items():
            c.act({"theta_u": s.Y[:, 0].copy(), "theta_l": s.Y[:, 1].copy()})
            if shadow:
                c.applied(np.full(2, 4.0))
        obs, *_ = venv.step(np.full((2, 1), 0.8))
        for shadow, c in est.items():
            err[shadow].append(np.abs(c.x[:, 0] - s.Y[:, 0]).max())  # the predicted motor angle
    assert np.mean(err[True][100:]) < 0.3 * np.mean(err[False][100:])


@pytest.mark.parametrize("mode", ["sensors", "motor"])
def test_student_sees_the_same_stacked_observation_command_and_integral_in_training_and_on_the_rig(mode) -> None:
    from agents.command import CommandSchedule
    from agents.controller import AgentController

    kw = {"observation": mode} if mode == "sensors" else {"observation": mode, "motor_history": 3}
    dim = 7  # 'sensors': 5 readings, the last voltage, the target; 'motor': 3 increments, 3 voltages, the target
    encoders = ("theta_u", "theta_l") if mode == "sensors" else ("theta_u",)

    class Recorder:  # an exported policy that records its inputs
        control_dt = 0.01
        obs_dim = 3 * dim + 1
        config = {
            "hyperparams": {
                "env_kwargs": kw,
                "frame_stack": 3,
                "motor_integral": True,
                "command_schedule": SCHEDULE,
            }
        }

        def act(self, x):
            self.x = np.array(x)
            return np.full((len(x), 1), 0.7, dtype=np.float32)

    venv = MotorIntegralVecEnv(
        _sensors_env(1, counts_per_rev=0, alpha0_range=(0.0, 0.0), episode_duration=1.0, **kw),
        0.01,
        command=CommandSchedule(**SCHEDULE),
        frames=3,
    )
    venv.seed(0)
    obs = venv.reset()
    assert obs.shape == (1, 3 * dim + 1) and not obs[0, : 2 * dim].any()  # zeros before the episode's start
    s = episode_batch(venv).system
    rec = Recorder()
    ctl = AgentController(rec, omega_ref=3.0, dt=0.01)
    ctl.reset({k: s.Y[:, j].copy() for j, k in enumerate(encoders)})
    commands = []
    for _ in range(90):  # past a wrap of the motor angle, within the episode (100 periods)
        u = ctl.act({k: s.Y[:, j].copy() for j, k in enumerate(encoders)})
        np.testing.assert_allclose(rec.x, obs, rtol=0, atol=2e-5)
        commands.append(float(obs[0, -2]))
        obs, *_ = venv.step((u / 5.0).reshape(-1, 1))
    assert commands[0] == 0.0 and 2.9 < max(commands) <= 3.0
    assert abs(s.Y[0, 0]) > np.pi and abs(obs[0, -1]) < 2.0  # the integral followed the motor angle


def test_tiny_dagger_from_lqg_2enc_lowers_the_imitation_error_and_exports_a_plain_network(tmp_path, capsys) -> None:
    import re

    import yaml

    from agents.export import ExportedPolicy
    from drillgym.cli import main

    entry = {
        "n_envs": 8,
        "n_timesteps": 0,
        "policy": "MlpPolicy",
        "normalize": False,
        "frame_stack": 4,
        "policy_kwargs": {"net_arch": {"pi": [64, 64], "vf": [16]}, "activation_fn": "relu"},
        "env_kwargs": {"observation": "sensors", "episode_duration": 1.0},
    }
    structure = {
        "motor_integral": True,
        "command_schedule": SCHEDULE,
        "distill": {"iterations": 3, "steps": 100, "epochs": 8, "whiten": 1e-6},
    }
    hp = tmp_path / "hp.yml"
    hp.write_text(yaml.safe_dump({"drillgym/Torsional-v0": entry, "drillgym": {"drillgym/Torsional-v0": structure}}))
    out = tmp_path / "student"
    args = ["train", "--env", "drillgym/Torsional-v0", "--algo", "ppo", "--hyperparams", str(hp), "--teacher"]
    with pytest.raises(SystemExit) as done:
        main(
            [
                *args,
                "lqg-2enc",
                "--timesteps",
                "0",
                "--seed",
                "0",
                "--no-progress",
                "--no-tensorboard",
                "--out",
                str(out),
            ]
        )
    assert done.value.code in (0, None)
    assert "policy: lqg-2enc" in (out / "config.yml").read_text()
    student = ExportedPolicy.load(out / "policy.npz")
    assert student.obs_dim == 4 * 7 + 1  # 4 frames of the sensors observation, then the integral
    mses = [float(x) for x in re.findall(r"action MSE ([0-9.]+)", capsys.readouterr().out)]
    assert len(mses) == 3 and mses[-1] < 0.5 * mses[0]
