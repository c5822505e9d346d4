"""Generated bad arguments for the public Python entry points: the Python API refuses what the CLI refuses.

Each test draws one argument of one function and a bad value for it (a string or None for a number,
NaN, infinity, a negative or zero value, a value beyond the rig's range, an unknown name, a setting
inconsistent with the configuration) and calls the function on tiny durations. The call passes when
it raises a :class:`drillgym.errors.DrillgymError` (an ``InputError`` for bad input) whose message
names the argument, or returns a documented valid result that is finite.
"""

from __future__ import annotations

import numpy as np
import pytest
from bad_inputs import GOOD_MODEL, HOSTILE_MODELS, build_hostile_models
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import drillgym
from drillgym.errors import DrillgymError, InputError

BAD_NUMBERS = [float("nan"), float("inf"), float("-inf"), "abc", "2", None, [1.0, "x"], object()]


def examples(n: int):
    """Deterministic Hypothesis settings with ``n`` examples, no shrinking."""
    return settings(
        derandomize=True,
        deadline=None,
        max_examples=n,
        database=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )


def refused(call, *names: str) -> str:
    """``call()`` raises a DrillgymError naming one of ``names``; returns its message."""
    with pytest.raises(DrillgymError) as err:
        call()
    msg = " ".join(str(err.value).split())
    assert msg and "np.float64" not in msg, msg
    if names:
        assert any(n in msg for n in names), f"names none of {names}: {msg}"
    return msg


def draw_kwargs(data, table: dict) -> tuple[str, object]:
    name = data.draw(st.sampled_from(sorted(table)), label="argument")
    return name, data.draw(st.sampled_from(table[name]), label="value")


# --------------------------------------------------------------------------------------- simulate


SIMULATE_BAD = {
    "config": ["nope", "", None, 3, "torsional-v0"],
    "u": BAD_NUMBERS + [1e6, -1e6],
    "duration": BAD_NUMBERS + [0.0, -1.0, 1e12],
    "dt": BAD_NUMBERS + [0.0, -1e-3, 1.0, 0.03],
    "alpha0": BAD_NUMBERS,
    "method": ["nope", "", None, 3],
    "record_every": [0, -1, 1.5, "2", None, 7],
    "effects": [["nope"], ["lateral_anisotropy"], [3], "nope"],
}


@examples(20)
@given(data=st.data())
def test_simulate(data):
    name, value = draw_kwargs(data, SIMULATE_BAD)
    kw = {"config": "torsional", "u": 3.0, "duration": 0.1, "dt": 1e-3}
    kw[name] = value
    try:
        traj = drillgym.simulate(kw.pop("config"), kw.pop("u"), kw.pop("duration"), **kw)
    except DrillgymError as exc:
        msg = " ".join(str(exc).split())
        assert any(n in msg for n in (name, "effect", "configuration", "voltage")), msg
        return
    # accepted: only if the value is documented as valid, and then the run must be right
    pytest.fail(f"simulate accepted {name}={value!r}: {len(traj.t)} samples")


@pytest.mark.parametrize(
    "kw,names",
    [
        ({"u": 1e6}, ("u", "voltage", "V")),
        ({"dt": 0.03}, ("dt", "duration")),
        ({"effects": ["lateral_anisotropy"]}, ("lateral_anisotropy",)),
    ],
)
def test_simulate_refuses_what_the_cli_refuses(kw, names):
    args = {"u": 1.0, **kw}
    refused(lambda: drillgym.simulate("torsional", args.pop("u"), 0.1, **args), *names)


def test_simulate_valid_run_is_finite():
    traj = drillgym.simulate("torsional", 3.0, 0.1, dt=1e-3, record_every=10)
    assert len(traj.t) == 11 and np.isfinite(traj.omega_l).all()


# --------------------------------------------------------------------------------------- envs


ENV_BAD = {
    "omega_ref": [float("nan"), float("inf"), -1.0, "abc", 1e9],
    "episode_duration": [0.0, -1.0, float("nan"), "abc"],
    "control_dt": [0.0, -0.01, float("nan"), 10.0],
    "observation": ["nope", "", 3],
    "randomize": [-0.5, float("nan"), 2.0],
    "method": ["nope"],
    "effects": [["nope"], ["lateral_anisotropy"]],
    "nope_kwarg": [1],
}


@examples(8)
@given(data=st.data())
def test_gymnasium_make(data):
    import gymnasium

    import drillgym.envs  # noqa: F401  (registers the ids)

    env_id = "drillgym/Torsional-v0"
    name, value = draw_kwargs(data, ENV_BAD)
    try:
        env = gymnasium.make(env_id, **{name: value})
    except DrillgymError as exc:
        assert name in str(exc) or "effect" in str(exc), str(exc)
        return
    try:
        obs, _ = env.reset(seed=0)
        pytest.fail(f"gymnasium.make({env_id!r}, {name}={value!r}) accepted; obs finite: {np.isfinite(obs).all()}")
    finally:
        env.close()


# --------------------------------------------------------------------------------------- controllers, evaluation


@pytest.mark.parametrize(
    "name,kw",
    [
        ("nope", {}),
        ("baseline@0", {}),
        ("baseline@-5", {}),
        ("baseline@abc", {}),
        ("baseline", {"config": "nope"}),
        ("agent:/no/such/policy.npz", {}),
    ],
)
def test_controllers_make(name, kw):
    import controllers

    refused(lambda: controllers.make(name, **kw), name.split("@")[0].split(":")[0], "config", "period", "nope")


#: arguments of controllers.make of the wrong type or value, with what the refusal names (drawn for several names)
MAKE_BAD = {
    "name": [None, 3, ["observer"]],
    "omega_ref": ["fast", [1.0, "x"], object(), float("nan"), -1.0],
    "dt": ["0.01", [0.01], 0.0, float("nan")],
    "u_max": ["5", -1.0],
    "counts_per_rev": [1.5, "2048", 0, -5],
    "hold": ["long"],
    "colour": [1],
    "model": [3, {"params": {}}, "/no/such/model.json"],
}
MAKE_FOR = {"counts_per_rev": "lqg-2enc", "hold": "lqg-2enc"}


@examples(30)
@given(data=st.data())
def test_controllers_make_refuses_wrong_types(data):
    """controllers.make raises a DrillgymError naming the argument for any wrong type or value (never a bare
    TypeError, ValueError or AttributeError from deep inside a constructor)."""
    import controllers

    arg, value = draw_kwargs(data, MAKE_BAD)
    name = MAKE_FOR.get(arg, data.draw(st.sampled_from(["observer", "lqg", "pi", "descent"]), label="controller"))
    if arg == "name":
        refused(lambda: controllers.make(value), "controller name")
    elif arg == "omega_ref":
        refused(lambda: controllers.make(name, omega_ref=value), "omega_ref")
    else:
        refused(lambda: controllers.make(name, **{arg: value}), arg, "model")


CLOSED_LOOP_BAD = {
    "controller": ["observer", None, 3],
    "omega_ref": ["fast", [2.0, "x"], float("nan")],
    "duration": ["0.1", None, 0.0, 1e-6],
    "counts_per_rev": ["x", -5, 1.5, [1, 2, 3]],
    "angle_noise": ["x", -1.0, float("inf")],
    "seed": ["x", 1.5, -1],
    "sim_dt": [0.0, float("nan"), "0.001"],
    "params": ["x"],
    "compiled": ["yes"],
}


@examples(25)
@given(data=st.data())
def test_run_closed_loop_refuses_wrong_types(data):
    """The compiled closed loop's entry point refuses a wrong argument in a DrillgymError naming it."""
    import controllers
    from controllers.evaluation.runner import run_closed_loop

    arg, value = draw_kwargs(data, CLOSED_LOOP_BAD)
    kw = {"controller": controllers.make("observer"), "config": "torsional", "omega_ref": [2.0, 3.0], "duration": 0.1}
    kw[arg] = value
    refused(lambda: run_closed_loop(**kw), arg, "period")


def test_run_closed_loop_refuses_a_model_given_as_params():
    import controllers
    from controllers.evaluation.runner import run_closed_loop

    m = drillgym.Model(effects=("motor_lag",), values={"tau_m": 0.03})
    msg = refused(lambda: run_closed_loop(controllers.make("observer"), "torsional", [2.0], 0.1, params=m), "params")
    assert "effects=model.composition" in msg


EVAL_BAD = {
    "controllers": [[], ["nope"], ["baseline@0"], ["agent:/no/such.npz"], ["baseline", "baseline"]],
    "configs": [[], ["nope"], ["upper"], ["free_vibration"], ["torsional", "torsional"], ["torsional", "TORSIONAL"]],
    "targets": [[], [float("nan")], [-1.0], [0.0], [1e9], ["abc"]],
    "duration": [0.0, -1.0, float("nan"), float("inf")],
    "window": [0.0, -1.0, float("nan"), 100.0],
    "plants": [0, -1, 1.5],
    "seed": [-1, 1.5],
    "workers": [0, -1],
}


@examples(10)
@given(data=st.data())
def test_evaluate(data):
    from controllers.evaluation import evaluate
    from controllers.evaluation.harness import check_evaluation_options

    name, value = draw_kwargs(data, EVAL_BAD)
    kw = dict(controllers=["baseline"], configs=["torsional"], targets=[1.0], duration=0.2, window=0.1)
    kw[name] = value
    refused(lambda: check_evaluation_options(**kw), name)
    args = (kw.pop("controllers"), kw.pop("configs"), ["rest"], kw.pop("targets"))
    refused(lambda: evaluate(*args, progress=False, **kw), name)


@pytest.mark.parametrize(
    "name, value", [("controllers", ["baseline", "pi", "baseline"]), ("configs", ["torsional", "TORSIONAL"])]
)
def test_evaluate_refuses_an_item_given_twice(name, value):
    """A controller or configuration named twice would be run and reported twice, as if two."""
    from controllers.evaluation.harness import check_evaluation_options

    kw = dict(controllers=["baseline"], configs=["torsional"], targets=[1.0], duration=0.2, window=0.1)
    kw[name] = value
    assert "given twice" in refused(lambda: check_evaluation_options(**kw), name)


@pytest.mark.parametrize(
    "kw",
    [{"path": 3}, {"path": None}, {"params": {"Jl": 0.04}}, {"trust": "no"}],
    ids=["int", "none", "params", "trust"],
)
def test_load_plants_refuses_wrong_argument_types(kw):
    from pathlib import Path

    from controllers.evaluation.plants_file import load_plants

    kw = {"path": Path(__file__).resolve().parents[1] / "examples" / "plants.yaml", **kw}
    refused(lambda: load_plants(**kw), "plants_file", "trust")


# --------------------------------------------------------------------------------------- bifurcation, parallel


BIF_BAD = {
    "umin": [float("nan"), -1.0, 10.0, float("inf")],
    "umax": [float("nan"), 0.0, -1.0, 60.0, float("inf")],
    "sweep_step": [float("nan"), -0.1, 1e-9, float("inf")],
    "sweep_duration": [0.0, 5.0, float("nan"), float("inf")],
    "ds_max": [0.0, -0.1, float("nan"), float("inf")],
}


@examples(12)
@given(data=st.data())
def test_compute_diagram_refuses_before_any_work(data):
    from drillgym.bifurcation import compute_diagram

    name, value = draw_kwargs(data, BIF_BAD)
    kw = dict(umin=0.0, umax=1.0, sweep_step=0.5, sweep_duration=30.0, ds_max=0.2)
    kw[name] = value
    calls = []
    refused(lambda: compute_diagram("torsional", drillgym.RigParams(), progress=calls.append, **kw), name)
    assert not calls, "work started before the refusal"


@pytest.mark.parametrize("config", ["free_vibration", "nope", ""])
def test_compute_diagram_configuration(config):
    from drillgym.bifurcation import compute_diagram

    refused(lambda: compute_diagram(config, drillgym.RigParams(), umax=1.0, sweep_step=0), config, "configuration")


@pytest.mark.parametrize(
    "address,kind",
    [("", InputError), ("nope", InputError), ("host:99999", InputError), ("127.0.0.1:1", DrillgymError)],
)
def test_ray_address_refused_in_seconds(address, kind):
    import time

    from drillgym.parallel import check_ray_address

    start = time.monotonic()
    with pytest.raises(kind) as err:
        check_ray_address(address)
    assert "--ray" in str(err.value) and time.monotonic() - start < 10


@pytest.mark.parametrize("workers", [0, -1])
def test_local_executor_workers(workers):
    from drillgym.parallel import LocalExecutor

    refused(lambda: LocalExecutor(workers), "workers")


# --------------------------------------------------------------------------------------- identification, comparison


@pytest.mark.parametrize("rate", [0.0, -1.0, float("nan"), float("inf"), "50", 1e6, 1e-3])
def test_prepare_experiment_rate(rate, tmp_path):
    from drillgym.identification import prepare_experiment
    from drillgym.io import read_timeseries

    path = tmp_path / "r.csv"
    drillgym.simulate("torsional", 3.0, 0.2).to_csv(path)
    ts = read_timeseries(path)
    refused(lambda: prepare_experiment(ts, "torsional", compare_rate_hz=rate), "rate")


@pytest.mark.parametrize("segment", [float("nan"), 0.0, float("inf"), "4", 1e-3])
def test_compare_segment(segment, tmp_path):
    from drillgym.diagnosis.compare import compare
    from drillgym.identification import prepare_experiment
    from drillgym.io import read_timeseries

    path = tmp_path / "r.csv"
    drillgym.simulate("torsional", 3.0, 0.2).to_csv(path)
    ex = prepare_experiment(read_timeseries(path), "torsional")
    try:
        res = compare(ex, drillgym.RigParams(), segment_s=segment)
    except DrillgymError as exc:
        assert "segment" in str(exc), str(exc)
        return
    pytest.fail(f"compare accepted segment_s={segment!r}: {res}")


DIAGNOSE_BAD = {
    "segment_s": ["abc", float("nan"), 0.0, float("inf"), True],
    "compare_rate_hz": ["x", 0.0, -5.0, float("nan"), 1e6],
    "lvdt_lowpass_hz": [-1.0, 0.0, float("inf"), "5"],
    "n_joint": [0, -1, 1.5, "2"],
    "max_effects": [0, -1, "a", 2.5],
    "effects": [["nope"], ["lateral_anisotropy"], 3],  # one string is one effect (as_sequence), not bad
    "base_effects": [["lvdt_skew"], ["nope"]],
    "effect_params": [{"nope": 1.0}, [("tau_m", 1.0)]],
    "refine_speeds": ["no", 1, None],
    "fixed_base": ["yes", 0],
    "discover": ["yes", 1],
    "candidate_out": ["/proc/x.py", "cand.txt", 3],
}


@pytest.fixture(scope="module")
def short_recording():
    from drillgym.identification.synthetic import synthetic_measurement

    return synthetic_measurement("torsional", duration=4.0, rate_hz=200.0, seed=1)


@examples(30)
@given(data=st.data())
def test_diagnose_refuses_its_settings_before_any_work(data, short_recording):
    """Every setting the command line checks is checked by the function too, before the search."""
    from drillgym.diagnosis import diagnose

    name, value = draw_kwargs(data, DIAGNOSE_BAD)
    kw = {name: value}
    if name == "candidate_out":
        kw["discover"] = True
    refused(lambda: diagnose(short_recording, **kw), name, "rate", "effect", "parameter")


@pytest.mark.parametrize("params", ["x", {"Ju": 1.0}, 3])
def test_diagnose_refuses_params_that_are_not_rig_params(params, short_recording):
    from drillgym.diagnosis import diagnose

    refused(lambda: diagnose(short_recording, params), "params")


REFIT_BAD = {
    "effects": [["lvdt_skew"], ["nope"], 3],
    "effect_params": [{"nope": 1.0}, [("tau_m", 1.0)]],
    "base_values": [{"tau_m": 1.0}, "x"],
    "fit": [["nope"], ["k"], "k", 3, ["km", "km"]],
    "refit_base": ["no", 1],
    "segment_s": ["x", float("nan"), 0.0],
    "compare_rate_hz": [0.0, "x", 1e6],
    "max_nfev": [0, 1.5, "a", -3],
}


@examples(20)
@given(data=st.data())
def test_refit_refuses_its_settings_before_any_work(data, short_recording):
    """``refit`` (what ``identify`` runs) refuses what the command line refuses."""
    from drillgym.diagnosis.refit import refit

    name, value = draw_kwargs(data, REFIT_BAD)
    refused(lambda: refit(short_recording, **{name: value}), name, "rate", "effect", "parameter", "--fit")


def test_refit_refuses_an_effect_the_model_holds_already(short_recording):
    """An added effect that ``base_effects`` holds is refused in one line, as ``identify --add-effect`` does, not
    merged into one (whose values would then be the added ones or the held ones, unsaid)."""
    from drillgym.diagnosis.refit import refit

    msg = refused(lambda: refit(short_recording, effects=["motor_lag"], base_effects=["motor_lag"]), "motor_lag")
    assert "base_effects" in msg and "fit=" in msg


def test_refit_takes_one_name_as_one_effect_and_one_parameter():
    """A single string is one item (not its characters), as ``compose`` takes it."""
    from drillgym.diagnosis.refit import RefitOptions

    o = RefitOptions(effects="motor_lag", fit="km")
    assert o.effects == ("motor_lag",) and o.fit == ("km",)


# --------------------------------------------------------------------------------------- signals


SIGNAL_BAD = {
    "duration": BAD_NUMBERS + [0.0, -1.0, 1e12],
    "rate_hz": BAD_NUMBERS + [0.0, -100.0, 8.0],
    "amplitude": BAD_NUMBERS + [0.0, -1.0, 51.0],
    "offset": [float("nan"), float("inf"), "1", None, 6.0, -5.0],
    "seed": ["abc", -1, 1.5],
    "fade_s": [float("nan"), -1.0, "x"],
}


@examples(25)
@given(data=st.data())
def test_signal_generators_refuse_what_the_signal_command_refuses(data):
    from drillgym.signals import quasi_random, sum_of_sines

    name, value = draw_kwargs(data, SIGNAL_BAD)
    make = data.draw(st.sampled_from([quasi_random, sum_of_sines]), label="generator")
    kw = {"duration": 2.0, "rate_hz": 100.0, name: value}
    refused(lambda: make(kw.pop("duration"), **kw), name)


@pytest.mark.parametrize(
    "t, u, name",
    [
        ([0.0, 0.1, 0.2], [0.0, float("nan"), 1.0], "u"),
        ([0.0, 0.1, 0.2], [0.0, 60.0, 1.0], "u"),
        ([0.0, 0.1, 0.1], [0.0, 1.0, 1.0], "time"),
        (["a", "b"], [0.0, 1.0], "t"),
    ],
)
def test_write_input_file_refuses_a_signal_no_run_can_take(t, u, name, tmp_path):
    from drillgym.signals import write_input_file

    refused(lambda: write_input_file(tmp_path / "in.csv", t, u), name)
    assert not (tmp_path / "in.csv").exists()


def test_write_input_file_never_replaces_a_file_of_another_kind(tmp_path):
    from drillgym.signals import write_input_file

    keep = tmp_path / "keep.npz"
    keep.write_bytes(b"the user's own")
    refused(lambda: write_input_file(keep, [0.0, 0.1], [0.0, 1.0]), "keep.npz")
    assert keep.read_bytes() == b"the user's own"


# --------------------------------------------------------------------------------------- equilibria, sweeps, batches


def _eq():
    from drillgym import equilibria

    return equilibria


def _bf():
    from drillgym import bifurcation

    return bifurcation


SHORT = dict(duration=1.0, window=0.5)
EQUILIBRIA_BAD = [
    ("omega", lambda: _eq().equilibrium_voltage("torsional", float("nan"))),
    ("omega", lambda: _eq().equilibrium_voltage("torsional", "x")),
    ("omega", lambda: _eq().slip_equilibrium("torsional", "x")),
    ("effects", lambda: _eq().slip_equilibrium("torsional", 1.0, effects=["lvdt_skew"])),
    ("n", lambda: _bf().equilibrium_branch("torsional", n=0)),
    ("n", lambda: _bf().equilibrium_branch("torsional", n="a")),
    ("voltages", lambda: _bf().sweep_constant("torsional", ["a"], **SHORT)),
    ("voltages", lambda: _bf().sweep_constant("torsional", [1e6], **SHORT)),
    ("dt", lambda: _bf().sweep_constant("torsional", [2.0], dt=0.3, **SHORT)),
    ("alpha0", lambda: drillgym.initial_state(alpha0="x")),
    ("alpha0", lambda: drillgym.initial_state(alpha0=float("nan"))),
    ("n", lambda: drillgym.BatchSimulator("torsional", "2")),
    ("n", lambda: drillgym.BatchSimulator("torsional", 2.5)),
]


@pytest.mark.parametrize("name, call", EQUILIBRIA_BAD)
def test_equilibria_sweeps_and_batches_refuse_before_any_run(name, call):
    """Refused in the caller's words, before a worker starts (its refusal would come back wrapped)."""
    refused(call, name)


# --------------------------------------------------------------------------------------- model files


@pytest.fixture(scope="module")
def hostile_models(tmp_path_factory):
    return build_hostile_models(tmp_path_factory.mktemp("hostile"))


def test_the_model_the_hostile_files_are_made_from_loads(tmp_path):
    import json

    (tmp_path / "good.json").write_text(json.dumps(GOOD_MODEL))
    assert drillgym.Model.load(tmp_path / "good.json").values["tau_m"] == GOOD_MODEL["effects"][0]["values"]["tau_m"]


@pytest.mark.parametrize("name", sorted(HOSTILE_MODELS))
def test_model_load_refuses_a_hostile_model_file(name, hostile_models):
    """Model.load raises a DrillgymError naming the file (never an OverflowError, a TypeError, or a model that
    silently drops or misplaces what the file says)."""
    refused(lambda: drillgym.Model.load(hostile_models[name]), hostile_models[name])


#: arguments of drillgym.Model of the wrong type or value (each refused in a DrillgymError naming it)
MODEL_BAD = {
    "effects": [3, None, 2.5, {"motor_lag": 1}],
    "values": [[1.0], "tau_m=0.03", {"tau_m": "0.03"}, {"tau_m": 10**400}, {"tau_m": None}],
    "std": [[1.0], {"Jl": "x"}, {"Jl": -1.0}, {"Jl": 10**400}],
    "provenance": [{"route": "user"}, "user"],
    "params": [{"Jl": 0.04}, "params.json"],
}


@examples(20)
@given(data=st.data())
def test_model_refuses_wrong_arguments(data):
    arg, value = draw_kwargs(data, MODEL_BAD)
    kw = {"effects": ("motor_lag",), "values": {"tau_m": 0.03}, arg: value}
    refused(lambda: drillgym.Model(**kw), arg)


@pytest.mark.parametrize("path", [None, 3, ["m.json"]])
def test_model_save_and_load_refuse_a_path_that_is_not_one(path):
    m = drillgym.Model(effects=("motor_lag",))
    refused(lambda: m.save(path), "path")
    refused(lambda: drillgym.Model.load(path), "path")


def test_model_save_refuses_an_unwritable_place_before_copying_an_effect_file(tmp_path):
    """Model.save refuses a place it cannot write in a DrillgymError (not an OSError), before it copies an effect
    file beside the model."""
    import shutil
    from pathlib import Path

    src = Path(__file__).resolve().parents[1] / "examples" / "effects" / "string_cubic.py"
    shutil.copy(src, tmp_path / "string_cubic.py")
    m = drillgym.Model(effects=(f"{tmp_path / 'string_cubic.py'}:string_cubic",))
    (tmp_path / "notes.txt").write_text("the user's\n")
    refused(lambda: m.save(tmp_path / "notes.txt" / "model.json"), "notes.txt")
    refused(lambda: m.save("/proc/drillgym_cannot/model.json"), "/proc")
    (tmp_path / "out.json").mkdir()
    refused(lambda: m.save(tmp_path / "out.json"), "out.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt", "out.json", "string_cubic.py"]
    assert not any((tmp_path / "out.json").iterdir())


@pytest.mark.parametrize("trust", ["no", 0, None, "False"])
def test_model_load_refuses_a_trust_that_is_not_a_bool(trust, tmp_path):
    """``trust="no"`` is truthy: read as a bool it would run the code it was meant to refuse."""
    drillgym.Model(effects=("motor_lag",)).save(tmp_path / "m.json")
    refused(lambda: drillgym.Model.load(tmp_path / "m.json", trust=trust), "trust")
