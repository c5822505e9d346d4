"""DAgger from the motor-encoder observer run in shadow: labels from the 'motor' observation, per-rig restart, the
settled integral the teacher takes from the student, the whitening of the student's inputs."""

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
    teacher.act(obs[None, :], target)  # the last step's increment, read as the next period starts
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


def test_settled_integral_starts_when_the_ramp_ends_for_low_targets_alike_in_training_and_on_the_rig() -> None:
    from agents.command import CommandSchedule, SpeedCommand
    from agents.controller import AgentController
    from agents.envs import MotorIntegralVecEnv, episode_batch
    from drillgym.envs.sb3 import make_sb3_vec

    spec = {"approach": 2.5, "hold": 0.05, "ramp": 0.1, "lag": 0.05, "order": 3, "settled_integral": True}
    sched = CommandSchedule.from_config(spec)
    assert list(sched.integrating([0.1, 0.2, 0.2], [1.0, 1.0, 3.0])) == [False, True, False]  # as the observer's
    assert CommandSchedule(**{**spec, "settled_integral": False}).integrating(0.1, 1.0).all()
    with pytest.raises(InputError, match="settled_integral"):
        CommandSchedule.from_config({**spec, "settled_integral": 1})
    cmd = SpeedCommand(sched, 2, 0.01)
    for _ in range(16):
        cmd.advance(np.array([1.0, 1.0]))
    assert list(cmd.integrating(np.array([1.0, 3.0]))) == [True, False]

    kw = {"observation": "motor", "motor_history": 2}

    class Recorder:  # an exported policy that records its inputs
        control_dt = 0.01
        obs_dim = 2 * 5 + 1
        config = {"hyperparams": {"env_kwargs": kw, "frame_stack": 2, "motor_integral": True, "command_schedule": spec}}

        def act(self, x):
            self.x = np.array(x)
            return np.full((len(x), 1), 0.9, dtype=np.float32)

    env = make_sb3_vec(
        "drillgym/Torsional-v0", 1, omega_ref=1.0, episode_duration=1.0, normalize_action=True, counts_per_rev=0, **kw
    )
    venv = MotorIntegralVecEnv(env, 0.01, command=sched, frames=2)
    venv.seed(0)
    obs = venv.reset()
    s = episode_batch(venv).system
    rec = Recorder()
    ctl = AgentController(rec, omega_ref=1.0, dt=0.01)
    ctl.reset({"theta_u": s.Y[:, 0].copy()})
    z = []
    for _ in range(40):
        u = ctl.act({"theta_u": s.Y[:, 0].copy()})
        np.testing.assert_allclose(rec.x, obs, rtol=0, atol=2e-5)
        z.append(float(obs[0, -1]))
        obs, *_ = venv.step((u / 5.0).reshape(-1, 1))
    assert not any(z[:15]) and abs(z[-1]) > 1e-3  # 0 until hold + ramp = 0.15 s, then the motor angle's excess


def test_given_integral_teacher_uses_the_students_integral_for_low_targets_only() -> None:
    import gymnasium as gym

    from agents.teachers import ShadowTeacher

    env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=1.5, normalize_action=True)
    obs, _ = env.reset(seed=3)
    names = env.unwrapped.observation_names
    targets = np.array([1.5, 1.5, 3.0, 3.0])
    own = ShadowTeacher("observer", 4, 0.01, names)
    given = ShadowTeacher("observer", 4, 0.01, names, given_integral=True)
    batch = np.repeat(obs[None, :], 4, axis=0)
    for t in (own, given):
        t.reset(np.arange(4), batch, targets)
    z = np.array([0.0, 3.0, 0.0, 3.0])
    a_own, a_given = own.act(batch, targets), given.act(batch, targets, z)
    assert a_given[0] == pytest.approx(a_own[0], abs=1e-9)  # z = 0: the observer's own integral before the ramp's end
    assert abs(a_given[1] - a_given[0]) > 1e-3  # a low target's law acts on the given integral
    assert a_given[3] == pytest.approx(a_given[2], abs=1e-9)  # the high branch has no integral
    with pytest.raises(InputError, match="needs the integral z"):
        given.act(batch, targets)
    with pytest.raises(InputError, match="given_integral needs a law"):
        ShadowTeacher("lqg-2enc", 1, 0.01, names, given_integral=True)


def test_whitening_passes_an_entry_constant_in_the_first_states_unscaled() -> None:
    import torch as th

    from agents.distill import _Whitening

    rng = np.random.default_rng(0)
    a = rng.standard_normal(2000)
    x = np.stack([a, a + 1e-3 * rng.standard_normal(2000), np.zeros(2000)], axis=1)  # the integral still at 0
    layer = th.nn.Linear(3, 4)
    white = _Whitening(x, 1e-6, layer)
    M = white.M.numpy()
    assert M[2, 2] == pytest.approx(1.0, rel=1e-3) and np.abs(M[:2, 2]).max() < 1e-6 and np.abs(M[2, :2]).max() < 1e-6
    assert np.abs(M[:2, :2]).max() > 100  # the nearly collinear pair is decorrelated (and amplified)
    probe = th.as_tensor(np.array([[0.3, 0.31, 5.0]]), dtype=th.float32)
    with th.no_grad():
        whitened = layer(white(probe))
        with white.folded():
            assert th.allclose(layer(probe), whitened, atol=1e-3)


def test_kept_observer_student_is_a_plain_network_on_the_motor_angle_with_the_settled_integral() -> None:
    from pathlib import Path

    from agents import load_policy
    from agents.controller import AgentController

    policy = load_policy(Path(__file__).parents[1] / "agents/policies/nominal_motor_observer_distilled/policy.npz")
    hp = policy.config["hyperparams"]
    assert hp["command_schedule"]["settled_integral"] and hp["distill"]["teacher_kwargs"]["given_integral"]
    assert policy.obs_dim == 16 * 33 + 1 and all(a in ("relu", "identity") for a in policy.meta["activations"])
    ctl = AgentController(policy, omega_ref=np.array([2.0, 4.0]))
    assert ctl.uses == ("theta_u",)
    ctl.reset({"theta_u": np.zeros(2)})
    for k in range(50):
        u = ctl.act({"theta_u": np.array([0.02, 0.04]) * k})
        assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= 5.0)
    assert not ctl.z.any()  # no integral before the ramp's end (2.0) nor for a target above 2.5 rad/s


def test_a_shadow_teacher_is_built_on_the_rigs_model_of_a_run_given_one(monkeypatch):
    """``train --model FILE --teacher observer``: the teacher runs the observer built on the rigs' model, as
    ``controllers.make("observer", model=...)``; without a model, on its nominal one."""
    from types import SimpleNamespace

    import gymnasium as gym

    import agents.teachers as teachers
    from agents.distill import _teacher
    from drillgym import Model, RigParams

    env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=1.5, normalize_action=True)
    names = env.unwrapped.observation_names
    options = SimpleNamespace(omega_ref_range=(1.0, 4.0), omega_ref=None, control_dt=0.01)
    batch = SimpleNamespace(options=options, obs_model=SimpleNamespace(names=names, dim=len(names)), omega_ref=None)
    model = Model(RigParams(), ("motor_lag",), {"tau_m": 0.03})
    built = []

    class Spy(teachers.ShadowTeacher):
        def __init__(self, *args, **kw):
            super().__init__(*args, **kw)
            built.append(self.controller)

    monkeypatch.setattr(teachers, "ShadowTeacher", Spy)
    _teacher("observer", 1, batch, {}, model=model)
    _teacher("observer", 1, batch, {})
    assert built[0].effects.composition.label == "motor_lag" and built[0].effects.values["tau_m"] == 0.03
    assert not built[1].effects.composition.effects
