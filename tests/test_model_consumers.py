"""The model travels: every consumer takes ``model=`` (or ``--model FILE``) and runs exactly the
simulator's run of that model (``simulate(..., model=m)``), which differs from its run without it by what the
model's effects contribute.  One library effect (``motor_lag``, compiled once) keeps the suite quick; a step in
the command makes the lag show."""

from __future__ import annotations

import contextlib
import io
import pickle
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import drillgym
from drillgym import Model, RigParams, simulate, simulate_batch
from drillgym.effects import EffectError
from drillgym.errors import InputError

TAU = 0.05  # s, the motor lag of the model
N, K0, U1 = 60, 20, 3.0  # control periods, the step's period, its voltage (V)
STEP = np.where(np.arange(N) >= K0, U1, 0.0)  # 0 V, then 3 V from 0.2 s
ENV = dict(omega_ref=4.0, alpha0_range=(0.0, 0.0), episode_duration=1.0, normalize_action=False)


@pytest.fixture(scope="module")
def m() -> Model:
    return Model(RigParams().replace(km=4.0), ("motor_lag",), {"tau_m": TAU})


@pytest.fixture(scope="module")
def model_file(m, tmp_path_factory):
    return m.save(tmp_path_factory.mktemp("model") / "model.json")


def _run_env(env, actions=STEP) -> np.ndarray:
    """(omega_u, omega_l, alpha) at the end of each control period under ``actions`` (V)."""
    env.reset(seed=0)
    return np.array([env.step(np.array([a], dtype=np.float32))[0][:3] for a in actions], dtype=float)


def _simulated(m: Model | None, duration: float = N * 0.01) -> np.ndarray:
    """The simulator's run of the model at the env's step (10 ms), the same voltage held per period."""
    traj = simulate("torsional", STEP, duration, dt=0.01, model=m)
    return np.column_stack([traj.omega_u, traj.omega_l, traj.alpha])[1:]


def run_cli(*argv) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``drillgym ARGV`` in this process (the compiled model is reused)."""
    from drillgym.cli import main

    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code or 0
    return code, out.getvalue(), err.getvalue()


# ------------------------------------------------------------------------------------------ environments


def test_an_env_runs_the_model_as_simulate_does(m, model_file):
    with_model = _run_env(gymnasium.make("drillgym/Torsional-v0", model=m, **ENV))
    sim = _simulated(m)
    np.testing.assert_allclose(with_model, sim, rtol=1e-6, atol=1e-6)  # float32 observations
    base = _run_env(gymnasium.make("drillgym/Torsional-v0", params=m.params, **ENV))
    lag = np.abs(base - with_model).max()
    assert lag > 0.1  # rad/s: what the motor lag contributes after the step
    np.testing.assert_allclose(base, _simulated(Model(m.params)), rtol=1e-6, atol=1e-6)
    from_file = _run_env(gymnasium.make("drillgym/Torsional-v0", model=str(model_file), **ENV))
    np.testing.assert_array_equal(from_file, with_model)
    env = gymnasium.make("drillgym/Torsional-v0", model=m, **ENV)
    again = pickle.loads(pickle.dumps(env))  # the spec holds the model's parts, which pickle
    assert again.unwrapped.options.rig_model == m and gymnasium.make(env.spec).unwrapped.options.rig_model == m


def test_the_vector_env_runs_the_model(m):
    venv = drillgym.envs.make_vec("drillgym/Torsional-v0", 2, model=m, **ENV)
    venv.reset(seed=0)
    rows = np.array([venv.step(np.full((2, 1), a, dtype=np.float32))[0][:, :3] for a in STEP], dtype=float)
    np.testing.assert_allclose(rows[:, 0], _simulated(m), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(rows[:, 0], rows[:, 1])
    assert venv.options.rig_model == m


@pytest.mark.parametrize("beside", [{"params": RigParams()}, {"effects": ["motor_lag"]}, {"effect_params": {}}])
def test_an_env_refuses_a_model_beside_its_parts(m, beside):
    with pytest.raises(InputError, match="option 'model': give model= or") as exc:
        gymnasium.make("drillgym/Torsional-v0", model=m, **beside)
    assert "\n" not in str(exc.value)


def test_a_nominal_task_runs_the_model(m):
    env = gymnasium.make("drillgym/Nominal-Motor-v0", model=m)
    assert env.unwrapped.options.rig_model == m


def test_a_population_task_draws_its_plants_around_the_model(m):
    from agents.benchmark_env import train_plants
    from drillgym.envs.tasks import get_task

    env = gymnasium.make("drillgym/Population-Motor-v0", model=m)
    o = env.unwrapped.options
    comp = o.effects
    assert comp.names[0] == "motor_lag" and "input_delay" in comp.names
    P = env.unwrapped.batch.randomizer.matrix
    km = P[:, comp.param_index("km")]
    assert np.all(np.abs(km / m.params.km - 1) <= 0.05 + 1e-12)  # +-5 % around the model's km
    assert abs(km.mean() / m.params.km - 1) < 0.01
    nominal = train_plants(get_task("drillgym/Population-Motor-v0"))
    assert not np.allclose(km, nominal.matrix[:, nominal.composition.param_index("km")])  # not the identified rig's
    assert np.all(P[:, comp.param_index("Ju")] == m.params.Ju)  # not in the set: the model's value


# ------------------------------------------------------------------------------------------ bifurcation


def test_bifurcation_with_a_model_equals_it_given_by_hand(m):
    from drillgym.bifurcation import equilibrium_branch, sweep_constant
    from drillgym.equilibria import RigModel
    from drillgym.parallel import LocalExecutor

    # open loop a motor lag leaves the equilibria and their stability as they are (its state follows the constant
    # voltage); string damping, a force, moves the Hopf points
    damped = Model(m.params, ("string_damping",), {"dtheta": 0.02})
    a = equilibrium_branch("torsional", model=damped, n=40)
    b = equilibrium_branch("torsional", RigModel(m.params, ["string_damping"], {"dtheta": 0.02}), n=40)
    c = equilibrium_branch("torsional", m.params, n=40)  # the model's base parameters without its effect
    assert [h.u for h in a.hopf] == [h.u for h in b.hopf]
    assert abs(a.hopf[-1].u - c.hopf[-1].u) > 0.1  # V: the damping moves the Hopf point
    np.testing.assert_array_equal(a.max_real, b.max_real)
    by_hand = RigModel(m.params, ["motor_lag"], {"tau_m": TAU})
    kw = dict(duration=2.0, window=1.0, dt=1e-2, executor=LocalExecutor())
    s1 = sweep_constant("torsional", [2.0], model=m, **kw)
    s2 = sweep_constant("torsional", [2.0], params=by_hand, **kw)
    np.testing.assert_array_equal(s1.stats, s2.stats)
    with pytest.raises(InputError, match="give model= or params, not both"):
        sweep_constant("torsional", [2.0], params=m.params, model=m, **kw)


def test_the_section_maps_simulations_run_its_model(m):
    from drillgym.bifurcation import equilibrium_branch
    from drillgym.bifurcation.poincare import SectionMap
    from drillgym.bifurcation.verification import section_returns
    from drillgym.configurations import Configuration
    from drillgym.equilibria import model_or_params

    rm = model_or_params(model=m)
    smap = SectionMap(
        Configuration.TORSIONAL, rm.p, equilibrium_branch("torsional", model=m, n=20).section_speed, composition=rm.comp
    )
    y0 = np.zeros((1, rm.n_state))
    _, _, batch = section_returns(smap, 3.0, y0, 0.5, dt=1e-3, with_batch=True)  # the lagged model, not the base
    traj = simulate("torsional", 3.0, 0.5, dt=1e-3, x0=y0[0], model=m)  # the lag state from 0 V
    np.testing.assert_allclose(batch[0].omega_u, traj.omega_u, rtol=1e-12, atol=1e-12)
    base = simulate("torsional", 3.0, 0.5, dt=1e-3, x0=y0[0, :8], params=m.params)
    assert np.abs(base.omega_u - batch[0].omega_u).max() > 0.01  # rad/s: the lag


# ------------------------------------------------------------------------------------------ agents


def test_training_envs_run_the_model(m):
    from agents.envs import make_training_env
    from agents.run_model import with_model

    venv = make_training_env("drillgym/Torsional-v0", 1, env_kwargs={"model": m, **ENV}, monitor=False)
    assert venv.get_attr("options")[0].rig_model == m
    task = make_training_env("drillgym/Nominal-Motor-v0", 1, env_kwargs={"model": m}, monitor=False)
    assert task.get_attr("options")[0].rig_model == m
    pop = make_training_env("drillgym/Torsional-v0", 1, env_kwargs={"model": m}, population="default", monitor=False)
    o = pop.get_attr("options")[0]
    assert o.rig_params == m.params and o.effects.names[0] == "motor_lag"
    hp, recorded = with_model({"env_kwargs": {"observation": "motor"}}, m, False)
    assert hp["env_kwargs"]["model"] is m and recorded["env_kwargs"]["model"]["effects"][0]["values"] == {"tau_m": TAU}
    with pytest.raises(InputError, match="give model= or the env option\\(s\\) effects"):
        with_model({"env_kwargs": {"effects": ["motor_lag"]}}, m, False)


@pytest.mark.filterwarnings("ignore:descent. the approach")  # a short run, as a quick check
def test_benchmark_scores_on_the_models_plant(m):
    from agents.benchmark import BenchmarkOptions, run_benchmark

    opts = BenchmarkOptions(duration=21.0, window=20.0, targets=(4.0,))
    lagged = run_benchmark("drillgym/Nominal-Motor-v0", ["descent"], opts, model=m)
    plain = run_benchmark("drillgym/Nominal-Motor-v0", ["descent"], opts, model=Model(m.params))
    assert lagged.settings["model"]["label"] == "motor_lag" and lagged.reduced
    assert lagged.scores[0].energy != plain.scores[0].energy  # the lag changes the run
    with pytest.raises(InputError, match="--plants"):
        run_benchmark("drillgym/Population-Motor-v0", ["descent"], BenchmarkOptions(plants=2), model=m)


# ------------------------------------------------------------------------------------------ command line


def test_cli_simulate_model_equals_the_python_run(m, model_file, tmp_path):
    from drillgym.io import read_input_signal, read_timeseries

    sig = tmp_path / "u.csv"
    sig.write_text("t,u\n0,0\n0.2,3\n0.4,3\n")  # covers 0.6 s: the last sample is held one interval
    out = tmp_path / "run.csv"
    code, _, err = run_cli("simulate", "--model", model_file, "--input", sig, "--duration", "0.6", "--out", out)
    assert code == 0, err
    ts = read_timeseries(out)
    traj = simulate("torsional", read_input_signal(sig), 0.6, model=m)
    np.testing.assert_allclose(ts.omega_l, traj.omega_l, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ts.omega_u, traj.omega_u, rtol=1e-12, atol=1e-12)
    base = simulate("torsional", read_input_signal(sig), 0.6, params=m.params)
    assert np.abs(base.omega_u - ts.omega_u).max() > 0.05  # rad/s: the lag


def test_cli_free_vibration_runs_a_model_without_its_motor_lag(m, model_file, tmp_path):
    from drillgym.io import read_timeseries

    out = tmp_path / "free.csv"
    with pytest.warns(UserWarning, match="effect motor_lag does not act in the free_vibration configuration"):
        code, _, err = run_cli(
            "simulate", "--config", "free_vibration", "--model", model_file, "--alpha0", "1", "--duration", "0.5",
            "--out", out,
        )  # fmt: skip
    assert code == 0, err
    base = simulate("free_vibration", 0.0, 0.5, params=m.params, alpha0=1.0)  # the model's base, no lag
    np.testing.assert_allclose(read_timeseries(out).omega_l, base.omega_l, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "argv, says",
    [
        (("simulate", "--u", "1", "--duration", "0.1", "--params", "{file}"), "--params"),
        (("simulate", "--u", "1", "--duration", "0.1", "--model", "{file}", "--params", "{file}"), "--model cannot go"),
        (("simulate", "--u", "1", "--duration", "0.1", "--model", "{file}", "--add-effect", "input_delay"), "--model"),
        (("simulate", "--u", "1", "--duration", "0.1", "--trust"), "--trust needs --model"),
        (("bifurcation", "--model", "{file}", "--params", "{file}"), "--model cannot go with --params"),
        (("rig", "emulate", "--model", "{file}", "--params", "{file}"), "--model cannot go with --params"),
        (
            ("benchmark", "drillgym/Population-Motor-v0", "--policy", "descent", "--model", "{file}", "--plants", "2"),
            "--model cannot go with --plants",
        ),
        (("train", "--model", "{file}", "--add-effect", "input_delay"), "--model cannot go with --add-effect"),
    ],
)
def test_cli_refuses_in_one_line(model_file, tmp_path, argv, says):
    argv = [a.replace("{file}", str(model_file)) for a in argv] + ["--out", str(tmp_path / "x.csv")]
    if argv[0] in ("rig", "benchmark"):
        argv = argv[:-2]
    if argv[0] in ("bifurcation", "train"):
        argv[-1] = str(tmp_path / "outdir")
    code, _, err = run_cli(*argv)
    assert code == 2, err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and says in lines[0], err
    assert not (tmp_path / "x.csv").exists()


EFFECTS_DIR = Path(__file__).resolve().parents[1] / "examples" / "effects"


def test_a_models_effect_that_does_not_act_is_left_out_with_a_warning_by_simulate_and_simulate_batch():
    mixed = Model(effects=("motor_lag", "lateral_anisotropy"), values={"tau_m": 0.03, "dk": 200.0})
    with pytest.warns(UserWarning, match="effect lateral_anisotropy does not act in the torsional configuration"):
        one = simulate("torsional", u=1.0, duration=0.1, model=mixed)
    with pytest.warns(UserWarning, match="effect lateral_anisotropy does not act in the torsional configuration"):
        many = simulate_batch("torsional", u=np.array([1.0, 2.0]), duration=0.1, model=mixed)
    lag_only = simulate("torsional", u=1.0, duration=0.1, model=Model(effects=("motor_lag",), values={"tau_m": 0.03}))
    np.testing.assert_array_equal(one.omega_u, lag_only.omega_u)  # the lag kept, the idle effect left out
    np.testing.assert_array_equal(many.omega_u[0], lag_only.omega_u)
    assert mixed.in_configuration("coupled") is mixed  # where both act: the model itself
    with pytest.raises(EffectError, match="^effects lateral_anisotropy: the effect does not act in the torsional"):
        simulate("torsional", u=1.0, duration=0.1, effects=["lateral_anisotropy"])  # named by the caller: refused


def test_a_model_and_its_copy_saved_elsewhere_are_equal(tmp_path):
    spec = f"{EFFECTS_DIR / 'motor_dead_zone.py'}:dead_zone"
    m = Model(effects=("motor_lag", spec), values={"tau_m": 0.03, "u0": 0.3})
    m.save(tmp_path / "m.json")  # the effect file is copied beside the model
    back = Model.load(tmp_path / "m.json")
    assert back.specs != m.specs and back == m and hash(back) == hash(m)
    assert back.replace(values={"tau_m": 0.03, "u0": 0.2}) != m


def test_a_models_encoders_travel_through_its_file(tmp_path):
    from drillgym import Encoders
    from drillgym.errors import ParameterError

    m = Model(effects=("motor_lag",), values={"tau_m": 0.03}, encoders=Encoders(2048, 2e-4))
    back = Model.load(m.save(tmp_path / "m.yaml"))
    assert back.encoders == Encoders(2048, 2e-4) and back == m and pickle.loads(pickle.dumps(m)) == m
    assert back != m.replace(encoders=None)
    with pytest.warns(UserWarning, match="motor_lag does not act in the free_vibration"):
        assert m.in_configuration("free_vibration").encoders == m.encoders
    (tmp_path / "bad.json").write_text('{"params": {}, "encoders": {"counts_per_rev": 20.5}}')
    with pytest.raises(ParameterError, match="bad.json: encoders: counts_per_rev must be a whole number >= 1"):
        Model.load(tmp_path / "bad.json")


def test_rig_emulate_reads_through_the_models_encoders(tmp_path):
    """`rig emulate --model` emulates the encoders the model carries (what identify read off the recording) unless
    --counts-per-rev is given; without a model, 8000."""
    from hw.commands.rig import emulated_plant

    coarse = Model(
        RigParams(), ("motor_lag",), {"tau_m": 0.03}, encoders=drillgym.Encoders(counts_per_rev=2048, angle_noise=0.0)
    )
    path = coarse.save(tmp_path / "coarse.json")
    base, comp, values, counts = emulated_plant(path, False, "torsional", None, None, None, None)
    assert (counts, comp.names, values["tau_m"]) == (2048, ("motor_lag",), 0.03)
    assert emulated_plant(path, False, "torsional", None, None, None, 4096)[3] == 4096
    assert emulated_plant(None, False, "torsional", None, None, None, None)[3] == 8000
