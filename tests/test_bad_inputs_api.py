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


EVAL_BAD = {
    "controllers": [[], ["nope"], ["baseline@0"], ["agent:/no/such.npz"]],
    "configs": [[], ["nope"], ["upper"], ["free_vibration"]],
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


@pytest.mark.parametrize("rate", [0.0, -1.0, float("nan"), float("inf")])
def test_prepare_experiment_rate(rate, tmp_path):
    from drillgym.identification import prepare_experiment
    from drillgym.io import read_timeseries

    path = tmp_path / "r.csv"
    drillgym.simulate("torsional", 3.0, 0.2).to_csv(path)
    ts = read_timeseries(path)
    refused(lambda: prepare_experiment(ts, "torsional", compare_rate_hz=rate), "rate")


@pytest.mark.parametrize("segment", [float("nan"), -1.0, 0.0, float("inf")])
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
