"""Residual agent on the observer controller: structure = observer at zero residual, training wrapper and
rig controller agree step by step, training end to end, errors."""

import gymnasium as gym
import numpy as np
import pytest

import controllers
import drillgym  # noqa: F401  (registers the envs)
from agents.envs import make_training_env
from agents.hyperparams import load_hyperparams
from agents.observer_residual import ObserverResidual
from agents.train import train
from drillgym.measurement import quantize_angle

HP = "agents/hyperparams/ppo_observer.yml"
FAST = {"n_envs": 2, "n_steps": 64, "batch_size": 64, "env_kwargs.episode_duration": 0.5}


def _overrides(extra: dict) -> dict:
    out: dict = {}
    for k, v in extra.items():
        if k.startswith("env_kwargs."):
            out.setdefault("env_kwargs", {})[k.split(".", 1)[1]] = v
        else:
            out[k] = v
    return out


def test_zero_residual_is_the_observer_controller():
    """With a = 0 the structure gives the voltages of controllers.make("observer") at the same period and
    options to 1e-6 V over the start from rest (1.5 s; after the break-away the law's high gains amplify
    round-off of the different batch sizes, the harness test of the kept policy covers the closed loop)."""
    env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=2.0, normalize_action=False).unwrapped
    env.reset(seed=2)
    sysm = env.batch.system
    ref = controllers.make("observer", config="torsional", omega_ref=2.0, dt=0.01)
    base = ObserverResidual("torsional", 0.5, dt=0.01)
    th = float(quantize_angle(sysm.theta_u[0]))
    ref.reset({"t": 0.0, "theta_u": th})
    base.start(1)
    base.reset(np.arange(1), np.array([th]), np.array([2.0]))
    for k in range(150):  # 1.5 s: before the break-away, where the two filters' round-off gets amplified
        th = float(quantize_angle(sysm.theta_u[0]))
        u_ref = ref.act({"t": 0.0, "theta_u": th})
        base.correct(np.array([th]))
        base.base()
        u = base.voltage(np.zeros(1))
        base.predict(u)
        assert u[0] == pytest.approx(u_ref, abs=1e-6), f"step {k}"
        env.step(np.array([u_ref]))
    assert abs(sysm.theta_u[0]) > 0.05  # the motor moved: a non-trivial trajectory


def test_training_wrapper_and_controller_agree(tmp_path):
    """A short training run writes a policy; fed the same encoder angles, AgentController builds the
    training wrapper's observation and returns the voltage the wrapper applies."""
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path,
        timesteps=256,
        seed=0,
        hyperparams=HP,
        overrides=_overrides(FAST),
        progress=False,
        tensorboard=False,
    )
    assert res.policy_path is not None and res.policy_path.is_file()
    ctrl = controllers.make(f"agent:{res.policy_path}", config="torsional", omega_ref=3.0)
    assert ctrl.uses == ("theta_u",)
    observer = load_hyperparams("ppo", "drillgym/Torsional-v0", HP)["observer"]  # the options it was trained with
    venv = make_training_env(
        "drillgym/Torsional-v0",
        1,
        seed=4,
        residual=0.5,
        base="observer",
        observer=observer,
        monitor=False,
        env_kwargs={"observation": "motor", "motor_history": 1, "omega_ref": 3.0, "episode_duration": 30.0},
    )
    obs = venv.reset()
    sysm = venv.venv.venv.batch.system
    ctrl.reset({"t": 0.0, "theta_u": float(quantize_angle(sysm.theta_u[0]))})
    for k in range(300):
        u = ctrl.act({"t": 0.0, "theta_u": float(quantize_angle(sysm.theta_u[0]))})
        a = ctrl.policy.act(obs)
        np.testing.assert_allclose(venv.base.voltage(a)[0], u, atol=1e-6, err_msg=f"step {k}")
        obs, *_ = venv.step(a)


def test_observer_base_errors():
    with pytest.raises(ValueError, match="needs a residual scale"):
        make_training_env("drillgym/Torsional-v0", 1, base="observer", env_kwargs={"observation": "motor"})
    with pytest.raises(ValueError, match="'motor' observation"):
        make_training_env(
            "drillgym/Torsional-v0", 1, residual=0.5, base="observer", env_kwargs={"observation": "sensors"}
        )
    with pytest.raises(ValueError, match="base must be 'observer'"):
        make_training_env("drillgym/Torsional-v0", 1, residual=0.5, base="pid")
    with pytest.raises(ValueError, match="positive voltage"):
        ObserverResidual("torsional", 0.0)


def test_a_rig_reset_alone_restarts_its_observer_and_law():
    """Rigs reset at different times (an early termination in a VecEnv) run as if each had its own
    observer controller: rig 1 restarted at step 50 matches a fresh single-rig structure (to 1e-4 V: batch
    sizes round differently, and a flip of the law's at-rest test on that round-off moves the voltage by ~3e-5 V)."""
    angles = 0.004 * np.arange(150) ** 1.3  # a motor speeding up (rad)
    observer = load_hyperparams("ppo", "drillgym/Torsional-v0", HP)["observer"]  # the kept agent's options
    both, alone0, alone1 = (ObserverResidual("torsional", 0.5, observer=observer) for _ in range(3))
    both.start(2)
    both.reset(np.arange(2), np.zeros(2), np.array([2.0, 3.0]))
    alone0.start(1)
    alone0.reset(np.arange(1), np.zeros(1), np.array([2.0]))
    alone1.start(1)
    for k, th in enumerate(angles):
        if k == 50:
            both.reset(np.array([1]), np.array([th]), np.array([4.0]))
            alone1.reset(np.arange(1), np.array([th]), np.array([4.0]))
        for b, z in ((both, [th, th]), (alone0, [th])) + (((alone1, [th]),) if k >= 50 else ()):
            b.correct(np.array(z))
            b.base()
            b.predict(b.voltage(np.full(len(z), 0.3)))
        assert both.u_base[0] == pytest.approx(alone0.u_base[0], abs=1e-4)
        if k >= 50:
            assert both.u_base[1] == pytest.approx(alone1.u_base[0], abs=1e-4)
            np.testing.assert_allclose(both.features()[1], alone1.features()[0], atol=1e-4)
    assert np.ptp(both.u_base) > 0  # the two rigs differ


def test_on_a_model_the_zero_residual_is_the_observer_built_on_that_model():
    """Built on a model with effects (a motor lag and an input delay: states in the filter), the base with a = 0
    gives the voltages of ``controllers.make("observer", model=...)`` to the bit, where the base built on the
    base parameters alone does not; ``controllers.make("agent:DIR", model=...)`` of an observer-based policy runs
    on that base, without the warning a policy that cannot use the effects gives."""
    from drillgym import Model, RigParams

    model = Model(RigParams(), ("motor_lag", "input_delay"), {"tau_m": 0.03, "delay": 0.02})
    targets = np.array([1.5, 3.0])
    ref = controllers.make("observer", config="torsional", omega_ref=targets, dt=0.01, model=model)
    on_model, nominal = ObserverResidual("torsional", 0.5, dt=0.01, model=model), ObserverResidual("torsional", 0.5)
    ref.reset({"theta_u": np.zeros(2)})
    for b in (on_model, nominal):
        b.start(2)
        b.reset(np.arange(2), np.zeros(2), targets)
    apart = 0.0
    for k in range(200):
        th = 0.003 * k**1.4 * np.array([0.5, 1.0])  # motors speeding up (rad)
        u_ref = ref.act({"theta_u": th})
        for b in (on_model, nominal):
            b.correct(th)
            b.base()
            b.predict(b.voltage(np.zeros(2)))
        np.testing.assert_array_equal(on_model.u_base, u_ref)
        apart = max(apart, float(np.max(np.abs(nominal.u_base - u_ref))))
    assert apart > 0.01, apart  # the model's effects change the base
    assert on_model.x.shape[0] > nominal.x.shape[0]  # the lag and the delay line in its filter

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "effects not used" warning
        agent = controllers.make("agent:agents/policies/torsional_motor_residual_observer", omega_ref=2.0, model=model)
    assert agent.base.model.Ad.shape == on_model.model.Ad.shape  # its filter holds the lag and the delay line
