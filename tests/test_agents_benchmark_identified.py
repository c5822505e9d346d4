"""Identified benchmark tasks: each held-out plant's identified model reaches the policy, read back from a folder."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from agents.benchmark import BenchmarkOptions, run_benchmark
from controllers.evaluation import population_jobs
from controllers.evaluation.identify import IdentifiedPlant, load_identified, save_identified
from controllers.evaluation.jobs import build_controller
from controllers.evaluation.population import sample_plants
from drillgym import Model, RigParams
from drillgym.envs.tasks import TASKS, BenchmarkTask, PlantSet
from drillgym.errors import InputError

TASK = "drillgym/Population-Motor-Identified-v0"
KEPT_RESIDUAL = "agents/policies/torsional_motor_residual_observer"


def _identified(params: RigParams, tau_m: float = 0.03, delay: float = 0.0) -> dict[int, IdentifiedPlant]:
    model = Model(params, ("motor_lag", "input_delay"), {"tau_m": tau_m, "delay": delay})
    found = IdentifiedPlant(model, ["motor_lag", "input_delay"], 12.5, {"tau_m": tau_m, "Tc": math.nan}, ["a warning"])
    return {0: found}


def _held_out_plant_0() -> tuple[RigParams, float, float]:
    """The first held-out plant's base parameters, motor lag and input delay (what a good identification finds)."""
    c = sample_plants(1, TASKS[TASK].plants.eval_seed).columns[0]
    base = {k: v for k, v in c.items() if k in RigParams.__dataclass_fields__}
    return replace(RigParams(), **base), c["tau_m"], c["delay"]


def test_an_identification_written_is_read_back_whole(tmp_path):
    save_identified(_identified(RigParams()), tmp_path / "ident")
    back = load_identified(tmp_path / "ident", 3)
    assert list(back) == [0]  # plants 1 and 2 were not written: left to identify
    p = back[0]
    assert list(p.model.names) == ["motor_lag", "input_delay"] and p.model.values["tau_m"] == pytest.approx(0.03)
    assert p.selected == ["motor_lag", "input_delay"] and p.seconds == 12.5 and p.warnings == ["a warning"]
    assert p.values["tau_m"] == 0.03 and math.isnan(p.values["Tc"])  # not selected: NaN again
    (tmp_path / "ident" / "plant_0" / "identification.json").unlink()
    with pytest.raises(InputError, match="model.json only"):
        load_identified(tmp_path / "ident", 1)


def test_the_policy_of_an_identified_task_is_built_on_the_plants_identified_model(tmp_path, monkeypatch):
    def no_identification(*args, **kwargs):
        raise AssertionError("the plant's identification was in the folder")

    monkeypatch.setattr(population_jobs, "identify_population", no_identification)
    opts = {"plants": 1, "targets": (3.0,), "duration": 40.0, "window": 10.0, "workers": 1}
    params, tau_m, delay = _held_out_plant_0()
    lowest = {}
    for label, km in (("good", params.km), ("km 60 % low", 0.4 * params.km)):
        folder = save_identified(_identified(replace(params, km=km), tau_m, delay), tmp_path / label)
        res = run_benchmark(TASK, ["observer"], BenchmarkOptions(**opts, identified_dir=folder))
        assert res.settings["identified"] == str(folder)
        lowest[label] = res.scores[0].median
    assert lowest == {"good": 3.0, "km 60 % low": math.inf}  # the observer ran each folder's model


def test_identified_tasks_are_population_variants_and_refuse_misuse():
    ids = [t for t in TASKS if t.endswith("-Identified-v0")]
    assert len(ids) == 4 and all(TASKS[t].identified and TASKS[t].plants.population for t in ids)
    with pytest.raises(InputError, match="needs a population"):
        BenchmarkTask("drillgym/X-v0", "torsional", "motor", PlantSet(False), identified=True)
    with pytest.raises(InputError, match="applies to an identified task"):
        run_benchmark("drillgym/Population-Motor-v0", ["observer"], BenchmarkOptions(plants=1, identified_dir="x"))


def test_a_policy_on_the_observer_base_gets_the_whole_identified_model_in_the_harness(tmp_path):
    """The harness's route (build_controller) gives agent:PATH the model, effects included: with its residual
    zeroed, the policy's voltages are observer@10's on that model."""
    weights = dict(np.load(f"{KEPT_RESIDUAL}/policy.npz", allow_pickle=True))
    weights["W2"], weights["b2"] = np.zeros_like(weights["W2"]), np.zeros_like(weights["b2"])
    meta = json.loads(str(weights["meta"]))
    meta["config"]["hyperparams"]["observer"] = {}  # the observer's own settings, as observer@10 runs them
    weights["meta"] = np.array(json.dumps(meta))
    np.savez(tmp_path / "policy.npz", **weights)
    model = Model(RigParams(), ("motor_lag", "input_delay"), {"tau_m": 0.04, "delay": 0.012})
    ref = np.array([2.0, 4.0])
    agent, label = build_controller(f"agent:{tmp_path / 'policy.npz'}", "torsional", ref, RigParams(), model)
    observer, _ = build_controller("observer@10", "torsional", ref, RigParams(), model)
    assert label == model.label
    for c in (agent, observer):
        c.reset({"theta_u": np.zeros(2)})
    t = np.arange(1, 300) * 0.01
    theta = np.outer(0.6 * t**2 / (1.0 + t), [1.0, 1.3]) + 0.002 * np.sin(7.0 * t)[:, None]
    u_agent = np.array([agent.act({"theta_u": th}) for th in theta])
    u_observer = np.array([observer.act({"theta_u": th}) for th in theta])
    assert np.ptp(u_observer) > 0.5  # the law acts on these angles
    np.testing.assert_allclose(u_agent, u_observer, rtol=0, atol=1e-9)


def test_only_the_plants_a_folder_lacks_are_identified_and_each_chunk_is_written(tmp_path, monkeypatch):
    from agents.identified_plants import identified_plants

    asked = []

    def fake_identification(n, seed, *args, indices=None, **kwargs):
        asked.append((seed, list(indices)))
        if len(asked) == 2:  # the second chunk: the first is on disk already
            assert sorted(load_identified(tmp_path, 6)) == [0, 1, 2]
        return {k: _identified(RigParams(), tau_m=0.01 * (k + 1))[0] for k in indices}

    monkeypatch.setattr(population_jobs, "identify_population", fake_identification)
    save_identified(_identified(RigParams()), tmp_path)  # plant 0 identified before
    task = TASKS[TASK]
    found = identified_plants(task, "train", 6, tmp_path, workers=1)
    assert asked == [(task.plants.train_seed, [1, 2]), (task.plants.train_seed, [3, 4]), (task.plants.train_seed, [5])]
    assert sorted(found) == list(range(6)) and found[0].model.values["tau_m"] == pytest.approx(0.03)
    assert found[5].model.values["tau_m"] == pytest.approx(0.06)
    with pytest.raises(InputError, match="plants must be in 1..20"):
        identified_plants(task, "held-out", 21)
    with pytest.raises(InputError, match="split must be one of"):
        identified_plants(task, "test", 1)
    with pytest.raises(InputError, match="no plants to identify"):
        identified_plants(TASKS["drillgym/Nominal-Motor-v0"], "train", 1)


def test_the_identified_folder_is_refused_where_it_cannot_be_used(tmp_path):
    a_file = tmp_path / "plants.json"
    a_file.write_text("{}")
    with pytest.raises(InputError, match="not a folder"):
        run_benchmark(TASK, ["observer"], BenchmarkOptions(plants=1, identified_dir=a_file))
    with pytest.raises(InputError, match="with a model"):
        run_benchmark(TASK, ["observer"], BenchmarkOptions(identified_dir=tmp_path), model=Model())
    assert a_file.read_text() == "{}"


def test_rig_runs_a_policy_on_the_observer_base_on_the_whole_model():
    """``rig run --model FILE --controller agent:PATH``: the rig's route hands the policy the model's effects."""
    from controllers.model import model_of
    from hw.runner import make_controller

    model = Model(RigParams(), ("motor_lag", "input_delay"), {"tau_m": 0.04, "delay": 0.012})
    on_model = make_controller(f"agent:{KEPT_RESIDUAL}", "torsional", 2.0, 0.01, model_of(model))
    on_params = make_controller(f"agent:{KEPT_RESIDUAL}", "torsional", 2.0, 0.01, RigParams())
    filters = on_model.base._ctrl.model, on_params.base._ctrl.model
    assert (filters[0].lag_index >= 0, filters[0].delay_steps) == (True, 1)  # the lag's state, the 12 ms delay line
    assert (filters[1].lag_index, filters[1].delay_steps) == (-1, 0)


def test_the_rows_name_the_model_a_policy_runs():
    """A policy on the observer base runs the observer built on the whole model: its rows name the model; a plain
    network reads none of the model's effects (it warns): its rows say ``base``, not the model's effects."""
    model = Model(RigParams(), ("motor_lag",), {"tau_m": 0.03})
    ref = np.array([2.0])
    _, label = build_controller(f"agent:{KEPT_RESIDUAL}", "torsional", ref, RigParams(), model)
    assert label == model.label == "motor_lag"
    with pytest.warns(UserWarning, match="uses the model's base parameters only"):
        _, label = build_controller("agent:agents/policies/torsional_motor_ppo", "torsional", ref, RigParams(), model)
    assert label == "base"
