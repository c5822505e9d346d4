"""Named benchmark tasks and ``drillgym benchmark``: ids, disjoint fixed plant lists, scores, aggregates,
refusals."""

import json
import math
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

import drillgym  # noqa: F401 - registers the ids
from agents.benchmark import BenchmarkOptions, _score, resolve_policies, run_benchmark
from agents.benchmark_command import parse_seeds
from agents.benchmark_env import eval_plants, plant_rows_equal, train_plants
from agents.benchmark_stats import iqm_interval
from controllers.evaluation.population import sample_plants
from drillgym.envs.tasks import TASKS, BenchmarkTask, EvaluationProtocol, PlantSet, get_task
from drillgym.errors import InputError, MissingFileError
from drillgym.io.jsonfile import dumps_json

POP = "drillgym/Population-Motor-v0"


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "drillgym.cli", *args], capture_output=True, text=True, timeout=300)


def test_every_task_id_is_registered_with_its_sensors():
    assert len(TASKS) == 12  # 4 nominal, 4 population, their 4 identified variants
    for tid, task in TASKS.items():
        assert tid in gymnasium.registry
        assert gymnasium.registry[tid].kwargs == {"task": tid}
        assert ("theta_l" in task.reads) == (task.sensors != "motor")
    env = gymnasium.make("drillgym/Nominal-Motor-v0")
    assert env.observation_space.shape == (33,)  # motor history 16: 2H + 1
    assert env.spec.max_episode_steps == 6000  # 60 s of 10 ms periods
    assert env.unwrapped.options.omega_ref_range == (0.5, 8.0)
    env = gymnasium.make("drillgym/Nominal-Motor-v0", motor_history=4)  # a free option
    assert env.observation_space.shape == (9,)


def test_a_task_refuses_the_options_it_fixes():
    with pytest.raises(InputError, match="fixes option 'observation'"):
        gymnasium.make("drillgym/Nominal-Motor-v0", observation="full")
    with pytest.raises(InputError, match="fixes option 'randomize'"):
        gymnasium.make(POP, randomize=0.1)
    with pytest.raises(InputError, match="unknown task"):
        get_task("drillgym/Nominal-Lidar-v0")


def test_train_and_held_out_plants_are_disjoint_and_the_documented_set():
    task = get_task(POP)
    tr, ev = train_plants(task), eval_plants(task)
    assert tr.n == 1000 and ev.n == 20
    assert plant_rows_equal(tr.matrix, ev.matrix) == 0
    assert not set(task.plants.train_streams()) & set(task.plants.eval_streams())
    np.testing.assert_array_equal(ev.matrix, sample_plants(20, 0).matrix)  # what `evaluate --seed 0` runs
    assert plant_rows_equal(ev.matrix, ev.matrix) == 20  # the comparison can find equal rows
    with pytest.raises(InputError, match="must differ"):
        PlantSet(True, train_seed=3, eval_seed=3)


def test_plant_lists_are_the_same_in_another_process():
    code = (
        "from agents.benchmark_env import train_plants, eval_plants; from drillgym.envs.tasks import get_task; "
        "t = get_task('Population-TwoEncoder-v0'); print(train_plants(t).matrix[[0, 999]].sum().hex(), "
        "eval_plants(t).matrix.sum().hex())"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    t = get_task("Population-TwoEncoder-v0")
    assert out.stdout.split() == [train_plants(t).matrix[[0, 999]].sum().hex(), eval_plants(t).matrix.sum().hex()]


def test_population_env_runs_a_training_plant_each_episode():
    env = gymnasium.make(POP).unwrapped
    tr = train_plants(get_task(POP)).matrix
    rows = set()
    for seed in range(4):
        env.reset(seed=seed)
        p = env.batch.system.params_matrix[0]
        assert plant_rows_equal(p[None], tr) == 1
        rows.add(tuple(p))
    assert len(rows) > 1  # drawn, not always the same plant


def test_iqm_and_interval_on_known_seeds():
    a = iqm_interval([1.0, 2.0, 3.0, 4.0])
    assert a.iqm == pytest.approx(2.5) and a.seeds == 4
    assert 1.0 <= a.ci_low <= a.iqm <= a.ci_high <= 4.0 and a.ci_low < a.ci_high
    b = iqm_interval([2.5, 3.0, 2.5, 2.5, 3.5])
    assert b.iqm == pytest.approx(8 / 3)
    one = iqm_interval([2.5])
    assert one.iqm == 2.5 and math.isnan(one.ci_low) and math.isnan(one.ci_high)
    inf = iqm_interval([2.5, math.inf, math.inf, 3.0, 3.0])  # a seed holding nothing in the middle half
    assert math.isinf(inf.iqm) and math.isinf(inf.ci_high)


def _rows(spec, held):
    """Harness-like rows: plant k holds the targets of held[k] (SSI 0.01), not the others (SSI 0.5)."""
    out = []
    for k, ok in enumerate(held):
        for w in (2.0, 3.0, 4.0):
            out.append(
                dict(controller=spec, config="torsional", scenario="plants", plant=k, omega_ref=w,
                     ssi=0.01 if w in ok else 0.5, offset=0.0, energy=10.0 * w, runaway=False)
            )  # fmt: skip
    return out


def test_score_takes_each_plants_lowest_held_target():
    task = get_task(POP)
    rows = _rows("descent", [{2.0, 3.0, 4.0}, {3.0, 4.0}, {2.0, 4.0}, {2.0, 3.0}])  # plant 3 fails 4 -> none
    s = _score(task, "descent", rows)
    assert s.plant_lowest == (2.0, 3.0, 4.0, math.inf)
    assert (s.median, s.p90, s.none_held) == (4.0, math.inf, 1)
    assert s.energy == pytest.approx(30.0) and s.ssi == pytest.approx(0.01)


def test_a_coupled_task_holds_a_target_only_below_the_whirl_threshold():
    """A run holding the speed without stick-slip but whirling past the protocol's threshold is not held on a
    coupled task; on a torsional task the same rows score as they did without whirl (its disc is clamped)."""
    coupled, torsional = get_task("Coupled-Population-Motor-v0"), get_task(POP)
    limit = coupled.protocol.whirl_threshold
    assert limit == torsional.protocol.whirl_threshold == 0.15
    rows = _rows("descent", [{2.0, 3.0, 4.0}, {2.0, 3.0, 4.0}, {3.0, 4.0}])
    for r in rows:  # plant 0 whirls at 2 rad/s, plant 2 at 3 rad/s (both held on SSI and speed there)
        r["whirl"] = 2 * limit if (r["plant"], r["omega_ref"]) in ((0, 2.0), (2, 3.0)) else 0.05
    s = _score(coupled, "descent", [{**r, "config": "coupled"} for r in rows])
    assert s.plant_lowest == (3.0, 2.0, 4.0) and s.whirl_limited == 2 and s.whirl == pytest.approx(0.05)
    t = _score(torsional, "descent", rows)
    assert t.plant_lowest == (2.0, 2.0, 3.0) and t.whirl_limited == 0
    assert json.loads(dumps_json(s.to_json()))["whirl_limited"] == 2
    with pytest.raises(InputError, match="whirl_threshold"):
        EvaluationProtocol(whirl_threshold=-1.0)


def test_policy_specs_and_seed_directories(tmp_path):
    for k in (1, 2, 4):
        (tmp_path / f"seed_{k}").mkdir()
    picked = resolve_policies([f"agent:{tmp_path}"], [1, 4])
    assert picked == [f"agent:{tmp_path / 'seed_1'}", f"agent:{tmp_path / 'seed_4'}"]
    assert len(resolve_policies([f"agent:{tmp_path}"])) == 3
    with pytest.raises(InputError, match="no seed_3/"):
        resolve_policies([f"agent:{tmp_path}"], [3])
    with pytest.raises(InputError, match="deterministic"):
        resolve_policies(["descent"], [1])
    with pytest.raises(InputError, match="one classical controller"):
        resolve_policies(["descent", "pi"])
    with pytest.raises(MissingFileError):
        resolve_policies([f"agent:{tmp_path / 'none'}"])
    assert parse_seeds("1-3,7") == [1, 2, 3, 7]
    with pytest.raises(InputError, match="--seeds"):
        parse_seeds("3-1")


def test_benchmark_scores_two_held_out_plants():
    res = run_benchmark(
        "drillgym/Population-TwoEncoder-v0",
        ["lqg-2enc"],
        BenchmarkOptions(plants=2, targets=(3.0, 4.0), duration=8.0, window=2.0),
    )
    s = res.scores[0]
    assert res.reduced and res.settings["plants"] == 2 and len(s.plant_lowest) == 2
    assert s.energy > 0 and s.ssi >= 0 and s.runaway == 0
    assert res.aggregates["p90"].iqm == s.p90 and res.aggregates["p90"].seeds == 1
    data = json.loads(dumps_json(res.to_json()))
    assert data["task"] == "drillgym/Population-TwoEncoder-v0" and data["reduced"] is True
    assert "REDUCED" in res.lines()[0]


def test_benchmark_refuses_bad_input_in_one_line(tmp_path):
    bad = [
        (["Nope", "--policy", "descent"], "unknown task"),
        (["Nominal-Motor-v0", "--policy", "lqg-2enc"], "reads theta_l"),
        (["Population-Motor-v0", "--policy", "descent", "--plants", "21"], "--plants must be in 1..20"),
        (["Nominal-Motor-v0", "--policy", "descent", "--plants", "2"], "--plants applies to a population task"),
        (["Population-Motor-v0", "--policy", "descent", "--json", str(tmp_path)], "--json"),
    ]
    for args, msg in bad:
        res = run_cli("benchmark", *args)
        assert res.returncode == 2, res.stderr
        assert msg in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr


def test_task_definitions_refuse_bad_values():
    with pytest.raises(InputError, match="sensors"):
        BenchmarkTask("drillgym/X-v0", "torsional", "lidar", PlantSet(False))
    with pytest.raises(InputError, match="torsional or coupled"):
        BenchmarkTask("drillgym/X-v0", "lateral", "motor", PlantSet(False))


def test_reference_table_lists_on_a_richer_task_only_the_policies_that_read_more():
    from agents.benchmark_table import candidate_policies, fits

    two, motor = get_task("Nominal-TwoEncoder-v0"), get_task("Nominal-Motor-v0")
    assert fits(two, "lqg-2enc") and not fits(two, "descent") and not fits(motor, "lqg-2enc")
    assert fits(motor, "descent") and "baseline" in candidate_policies()


def test_the_coupled_tables_add_the_whirl_columns_and_the_torsional_ones_keep_theirs():
    from agents.benchmark_table import table_header

    torsional, coupled = table_header(get_task("Nominal-Motor-v0")), table_header(get_task("Coupled-Nominal-Motor-v0"))
    assert torsional.startswith("| policy | median (rad/s) | 90th pct (rad/s) | SSI | energy (J/run) |")
    assert "| SSI | whirl | plants limited by whirl | energy (J/run) |" in coupled and "whirl" not in torsional
