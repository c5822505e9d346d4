"""Teacher -> student distillation (DAgger): a full-state teacher taught to a motor-side network."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
import yaml

import drillgym  # noqa: F401
from agents.envs import episode_batch
from agents.export import ExportedPolicy
from agents.train import train


def _teacher(path) -> None:
    """A linear 'full'-observation teacher whose action depends on the target: a = 0.1 omega_ref - 0.5."""
    meta = {
        "format": 1,
        "activations": ["identity"],
        "output": "clip",
        "obs_dim": 5,
        "config": {
            "env_id": "drillgym/Torsional-v0",
            "algo": "ppo",
            "hyperparams": {"env_kwargs": {"observation": "full"}},
        },
    }
    np.savez(
        path,
        meta=np.array(json.dumps(meta)),
        action_low=np.float32([-1]),
        action_high=np.float32([1]),
        W0=np.float32([[0.0, 0.0, 0.0, 0.0, 0.1]]),
        b0=np.float32([-0.5]),
    )


def test_student_on_the_motor_side_learns_the_teachers_actions(tmp_path) -> None:
    _teacher(tmp_path / "teacher.npz")
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path / "student",
        timesteps=0,
        seed=0,
        progress=False,
        tensorboard=False,
        teacher=tmp_path / "teacher.npz",
        overrides={"n_envs": 8, "env_kwargs": {"episode_duration": 1.0}},
        distill_kwargs={"iterations": 2, "steps": 60, "epochs": 60, "lr": 3e-3},
    )
    assert res.timesteps == 0
    cfg = yaml.safe_load((tmp_path / "student" / "config.yml").read_text())
    assert (
        cfg["teacher"]["policy"].endswith("teacher.npz") and cfg["hyperparams"]["env_kwargs"]["observation"] == "motor"
    )
    student = ExportedPolicy.load(res.policy_path)
    assert student.obs_dim == 33  # the motor side only (the privileged critic's entries are not deployed)
    refs = (2.5, 4.0, 5.5, 7.0)  # the states the student visits (DAgger trained it on those)
    spread = [0.1 * ref - 0.5 for ref in refs]
    assert _median_error(student, refs) < 0.05 < np.ptp(spread) / 4  # follows the target dependence it was taught


def _median_error(student, refs) -> float:
    """Median |student action - the synthetic teacher's 0.1 * ref - 0.5| over 60 periods at each target."""
    errors = []
    for ref in refs:
        env = gym.make("drillgym/Torsional-v0", observation="motor", omega_ref=ref, episode_duration=1.0)
        obs, _ = env.reset(seed=1)
        for _ in range(60):
            a = student.act(obs)
            errors.append(abs(float(a[0]) - (0.1 * ref - 0.5)))
            obs, *_ = env.step(a)
    return float(np.median(errors))


def test_second_dagger_stage_continues_from_the_first_with_its_own_options(tmp_path) -> None:
    _teacher(tmp_path / "teacher.npz")
    common = dict(
        timesteps=0,
        seed=0,
        progress=False,
        tensorboard=False,
        teacher=tmp_path / "teacher.npz",
        overrides={"n_envs": 8, "env_kwargs": {"episode_duration": 1.0}},
    )
    # the first stage does nothing (0 rounds): whatever the student knows comes from the second
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path / "staged",
        **common,
        distill_kwargs={"iterations": 0, "steps": 60, "epochs": 60, "lr": 3e-3, "then": {"iterations": 2}},
    )
    student = ExportedPolicy.load(res.policy_path)
    # the teacher's actions at 2.5 and 7 rad/s: -0.25 and +0.2 (an untrained actor gives about 0)
    assert _median_error(student, (2.5, 7.0)) < 0.05
    with pytest.raises(ValueError, match="distill.then"):
        train(
            "drillgym/Torsional-v0",
            "ppo",
            tmp_path / "bad",
            **common,
            distill_kwargs={"iterations": 0, "then": {"teacher": "flatness"}},
        )


def test_flatness_teacher_holds_a_low_target_from_rest_on_the_true_state() -> None:
    from agents.teachers import FlatnessTeacher
    from drillgym.envs.sb3 import make_sb3_vec

    venv = make_sb3_vec(
        "drillgym/Torsional-v0",
        2,
        observation="full",
        omega_ref=2.0,
        alpha0_range=(0.0, 0.0),
        episode_duration=40.0,
        normalize_action=True,
    )
    venv.seed(0)
    venv.reset()
    s = venv.venv.batch.system
    teacher = FlatnessTeacher(2, dt=0.01)
    teacher.reset(np.arange(2), np.full(2, 2.0))
    w = []
    for k in range(3000):
        venv.step(teacher.act(s.omega_u, s.alpha, s.omega_l).reshape(-1, 1))
        if k >= 2000:
            w.append(s.omega_l.copy())
    w = np.array(w)
    # open loop, 2 rad/s sticks and slips from rest (the stick-slip region reaches 6.63 rad/s)
    assert np.all((w.max(0) - w.min(0)) / (2 * w.mean(0)) < 0.1)
    assert np.all(np.abs(w.mean(0) / 2.0 - 1.0) < 0.02)


def test_population_randomizer_draws_the_uncertainty_set() -> None:
    import pytest

    from agents.population import PopulationRandomizer
    from drillgym import RigParams
    from drillgym.effects import compose

    comp, _ = compose(["motor_lag", "input_delay", "position_friction"], {})
    r = PopulationRandomizer(comp, RigParams())
    rows = np.array([r.sample(np.random.default_rng(k)) for k in range(300)])
    km = rows[:, comp.param_index("km")] / RigParams().km
    tau = rows[:, comp.param_index("tau_m")]
    amp = np.hypot(rows[:, comp.param_index("pf_c1")], rows[:, comp.param_index("pf_s1")])
    assert 0.95 <= km.min() < 0.97 and 1.03 < km.max() <= 1.05  # plants.yaml: km +/- 5 %
    assert 1e-3 <= tau.min() < 0.01 and 0.04 < tau.max() <= 0.05
    assert amp.max() <= 0.2 + 1e-12 and rows[:, comp.param_index("Tcl")].std() == 0.0  # not in the set
    with pytest.raises(ValueError, match="lacks the population's effects"):
        PopulationRandomizer(compose(["motor_lag"], {})[0], RigParams())
    mixed = PopulationRandomizer(comp, RigParams(), nominal_fraction=0.5)
    rows = np.array([mixed.sample(np.random.default_rng(k)) for k in range(200)])
    nominal = rows[:, comp.param_index("km")] == RigParams().km
    assert 0.35 < nominal.mean() < 0.65  # about half the rigs are the nominal one
    assert np.all(rows[nominal, comp.param_index("pf_c1")] == 0.0) and np.all(
        rows[nominal, comp.param_index("delay")] == 0.0
    )
    assert np.all(rows[nominal, comp.param_index("tau_m")] == 1e-3)  # the set's lower bound: "no lag"
    with pytest.raises(ValueError, match="nominal_fraction"):
        PopulationRandomizer(comp, RigParams(), nominal_fraction=1.5)


def test_population_below_a_target_speed_is_the_nominal_rig_and_the_env_passes_the_target() -> None:
    from agents.population import PopulationRandomizer, population_env_kwargs, use_population
    from drillgym import RigParams
    from drillgym.effects import compose
    from drillgym.envs.sb3 import make_sb3_vec

    comp, _ = compose(["motor_lag", "input_delay", "position_friction"], {})
    r = PopulationRandomizer(comp, RigParams(), nominal_below=5.5)
    km = comp.param_index("km")
    low = np.array([r.sample(np.random.default_rng(k), 2.0)[km] for k in range(50)])
    high = np.array([r.sample(np.random.default_rng(k), 6.0)[km] for k in range(50)])
    assert np.all(low == RigParams().km) and high.std() > 0.01 * RigParams().km
    with pytest.raises(ValueError, match="nominal_below"):
        PopulationRandomizer(comp, RigParams(), nominal_below=-1.0)
    # the env draws each episode's target first and hands it to the randomizer
    kw = population_env_kwargs(
        {"observation": "motor", "omega_ref_range": [1.5, 8.0], "normalize_action": True}, "default"
    )
    venv = make_sb3_vec("drillgym/Torsional-v0", 64, **kw)
    use_population(venv, "default", nominal_below=5.5)
    venv.seed(3)
    venv.reset()
    batch = episode_batch(venv)
    target, rows = batch.omega_ref, batch.system.params_matrix
    assert np.all(rows[target < 5.5, km] == RigParams().km)
    assert np.mean(rows[target >= 5.5, km] != RigParams().km) > 0.9
    venv.close()


def test_motor_integral_is_the_same_in_training_and_on_the_rig(tmp_path) -> None:
    from agents.controller import AgentController
    from agents.envs import MotorIntegralVecEnv
    from agents.integral import advance
    from drillgym.envs.sb3 import make_sb3_vec

    venv = MotorIntegralVecEnv(
        make_sb3_vec(
            "drillgym/Torsional-v0",
            2,
            observation="motor",
            motor_history=4,
            omega_ref=3.0,
            episode_duration=0.2,
            normalize_action=True,
        ),
        0.01,
    )
    venv.seed(0)
    obs = venv.reset()
    z = np.zeros(2)
    for _ in range(25):  # over an episode's end (20 periods)
        obs, _, done, infos = venv.step(np.full((2, 1), 0.8))
        last = np.array([i["terminal_observation"][:-1] if d else o[:-1] for o, d, i in zip(obs, done, infos)])
        z = advance(z, last, 0.01)
        if done.any():
            assert np.allclose([i["terminal_observation"][-1] for i in infos], z)
            z[:] = 0.0
        assert np.allclose(obs[:, -1], z, atol=1e-6)
    assert 0 < np.abs(z).max() < 2.0
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path / "student",
        timesteps=0,
        seed=0,
        progress=False,
        tensorboard=False,
        teacher="flatness",
        overrides={"n_envs": 4, "motor_integral": True, "env_kwargs": {"episode_duration": 0.3, "motor_history": 4}},
        distill_kwargs={"iterations": 2, "steps": 20, "epochs": 2, "beta": 0.5, "noise": 0.1},
    )
    student = ExportedPolicy.load(res.policy_path)
    assert student.obs_dim == 4 + 4 + 1 + 1  # increments, voltages, target, integral
    ctl = AgentController(student, omega_ref=3.0, dt=0.01)
    ctl.reset({"theta_u": np.zeros(1)})
    assert np.isfinite(ctl.act({"theta_u": np.zeros(1)})).all()
    assert np.isfinite(ctl.act({"theta_u": np.full(1, 0.01)})).all()
    assert abs(ctl.z[0] - 0.01 * (1.0 - 3.0)) < 1e-6  # one period at 1 rad/s towards 3 rad/s


def test_zero_timesteps_need_a_teacher(tmp_path) -> None:
    import pytest

    with pytest.raises(ValueError, match="without a teacher"):
        train("drillgym/Torsional-v0", "ppo", tmp_path, timesteps=0, progress=False, tensorboard=False)


def test_command_schedule_reaches_the_target_from_above_and_is_the_same_on_the_rig(tmp_path) -> None:
    import pytest

    from agents.command import CommandSchedule, SpeedCommand
    from agents.controller import AgentController
    from agents.envs import MotorIntegralVecEnv
    from drillgym.envs.sb3 import make_sb3_vec

    sched = CommandSchedule(approach=8.5, hold=8.0, ramp=20.0, lag=0.0)
    assert np.allclose(sched([0.0, 8.0, 18.0, 28.0, 40.0], 2.5), [8.5, 8.5, 5.5, 2.5, 2.5])
    assert np.allclose(sched([0.0, 18.0], 9.0), 9.0)  # a target above the approach is commanded at once
    cmd = SpeedCommand(CommandSchedule(lag=1.0), 2, 0.01)
    w = []
    for _ in range(4000):
        cmd.advance(np.array([2.5, 9.0]))
        w.append(cmd.value)
    w = np.array(w)
    assert 8.0 < w[1000, 0] < 8.5 and abs(w[-1, 0] - 2.5) < 1e-3 and abs(w[-1, 1] - 9.0) < 1e-6
    assert np.all(np.diff(w[:, 1]) >= 0) and w[0, 0] < 0.01  # from rest, smoothly
    with pytest.raises(ValueError, match="unknown keys"):
        CommandSchedule.from_config({"approach": 8.5, "slope": 1.0})

    short = {"approach": 6.0, "hold": 0.05, "ramp": 0.1, "lag": 0.05}
    res = train(
        "drillgym/Torsional-v0",
        "ppo",
        tmp_path / "student",
        timesteps=0,
        seed=0,
        progress=False,
        tensorboard=False,
        teacher="flatness",
        overrides={
            "n_envs": 4,
            "motor_integral": True,
            "command_schedule": short,
            "env_kwargs": {"episode_duration": 0.3, "motor_history": 4},
        },
        distill_kwargs={"iterations": 1, "steps": 20, "epochs": 1, "population": "default"},
    )
    student = ExportedPolicy.load(res.policy_path)
    venv = MotorIntegralVecEnv(
        make_sb3_vec(
            "drillgym/Torsional-v0",
            1,
            observation="motor",
            motor_history=4,
            omega_ref=3.0,
            episode_duration=0.3,
            normalize_action=True,
            alpha0_range=(0.0, 0.0),
            counts_per_rev=0,
        ),
        0.01,
        command=CommandSchedule(**short),
    )
    venv.seed(0)
    obs = venv.reset()
    s = episode_batch(venv).system
    ctl = AgentController(student, omega_ref=3.0, dt=0.01)
    ctl.reset({"theta_u": s.Y[:, 0].copy()})
    commands = []
    for _ in range(25):  # the rig's controller builds the training env's observation, command and integral
        u = ctl.act({"theta_u": s.Y[:, 0].copy()})
        assert np.array_equal(np.hstack([ctl.stack, ctl.z[:, None].astype(np.float32)]), obs)
        commands.append(float(obs[0, -2]))
        obs, *_ = venv.step((u / 5.0).reshape(-1, 1))
    assert commands[0] == 0.0 and max(commands) > 3.5  # the command rose above the 3 rad/s target


def test_per_plant_teacher_is_designed_on_each_rigs_true_parameters() -> None:
    import pytest

    from agents.teachers import FlatnessTeacher
    from drillgym import RigParams

    n = 4
    nominal = FlatnessTeacher(n, dt=0.01, bandwidth=1.5, tau_ref=0.1)
    plant = FlatnessTeacher(n, dt=0.01, bandwidth=1.5, tau_ref=0.1, per_plant=True)
    rows = np.array([RigParams().scaled(Ts=f, km=1.0 / f).to_vector() for f in (1.0, 1.0, 1.2, 0.8)])
    plant.set_plants(np.arange(n), rows)
    for t in (nominal, plant):
        t.reset(np.arange(n), np.full(n, 2.5))
        t.law.y[:] = 2.5  # the reference's lags settled at the target
    from drillgym.friction import lower_friction

    rng = np.random.default_rng(0)
    alpha_eq = -float(lower_friction(np.array([2.5]))[0]) / RigParams().ktheta  # the winding at 2.5 rad/s
    for _ in range(20):  # states near that equilibrium (no voltage saturation)
        wu, wl = rng.uniform(2.3, 2.7, n), rng.uniform(2.3, 2.7, n)
        al = alpha_eq + rng.uniform(-0.05, 0.05, n)
        un, up = nominal.act(wu, al, wl), plant.act(wu, al, wl)
        assert np.allclose(un[:2], up[:2], atol=1e-12)  # rigs 0, 1 run the nominal plant
        assert np.all(np.abs(un) < 1) and np.all(np.abs(up) < 1)
        assert np.all(np.abs(un[2:] - up[2:]) > 1e-3)  # the others another brake and motor constant
    with pytest.raises(ValueError, match="per_plant"):
        nominal.set_plants(np.arange(n), rows)


def test_rl_training_env_draws_its_rigs_from_the_population() -> None:
    import pytest

    from agents.envs import make_training_env
    from drillgym import RigParams

    venv = make_training_env(
        "drillgym/Torsional-v0", 8, seed=1, env_kwargs={"observation": "motor"}, population="default"
    )
    venv.reset()
    system = episode_batch(venv).system
    km = system.params_matrix[:, system.composition.param_index("km")] / RigParams().km
    assert km.std() > 0 and np.all(np.abs(km - 1) <= 0.05 + 1e-12)  # plants.yaml: km +/- 5 %
    assert {"motor_lag", "input_delay"} <= set(system.composition.names)
    venv.close()
    with pytest.raises(ValueError, match="plain actions"):
        make_training_env(
            "drillgym/Torsional-v0", 2, env_kwargs={"observation": "motor"}, residual=1.5, population="default"
        )


def test_distillation_learning_rate_falls_geometrically_to_its_final_value():
    from agents.distill import round_learning_rate

    rates = [round_learning_rate(1e-3, 1e-5, i, 5) for i in range(5)]
    assert rates[0] == pytest.approx(1e-3) and rates[-1] == pytest.approx(1e-5)
    assert rates[2] == pytest.approx(1e-4)  # halfway in log
    assert round_learning_rate(1e-3, None, 3, 5) == 1e-3
    with pytest.raises(ValueError, match="positive"):
        round_learning_rate(1e-3, 0.0, 1, 5)


def test_each_dagger_round_is_reported_with_its_action_error(tmp_path) -> None:
    """``on_round(i, mse)`` is called after every round's regression (to snapshot or validate the student)."""
    from stable_baselines3 import PPO

    from agents.distill import distill
    from drillgym.envs.sb3 import make_sb3_vec

    _teacher(tmp_path / "teacher.npz")
    kw = {"observation": "motor", "episode_duration": 1.0}
    model = PPO(
        "MlpPolicy", make_sb3_vec("drillgym/Torsional-v0", 4, normalize_action=True, **kw), n_steps=8, batch_size=8
    )
    seen = []
    out = distill(
        model,
        "drillgym/Torsional-v0",
        kw,
        tmp_path / "teacher.npz",
        n_envs=4,
        iterations=3,
        steps=10,
        epochs=1,
        on_round=lambda i, mse: seen.append((i, mse)),
    )
    assert [i for i, _ in seen] == [0, 1, 2]
    assert seen[-1][1] == out["mse"] and all(np.isfinite(m) for _, m in seen)
