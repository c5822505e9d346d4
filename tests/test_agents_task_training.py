"""Training on a named benchmark task: the task's options and training plants, refusals of what it fixes."""

import subprocess
import sys

import pytest

from agents.batch import episode_batch
from agents.benchmark_env import eval_plants, plant_rows_equal, train_plants
from agents.envs import make_training_env
from agents.task_training import task_env_kwargs
from agents.train import _settings
from drillgym.envs.tasks import get_task
from drillgym.errors import InputError

POP = "drillgym/Population-Motor-v0"


def test_training_env_of_a_population_task_runs_its_training_plants_only():
    venv = make_training_env(POP, 3, seed=5, env_kwargs={"motor_history": 8})
    batch = episode_batch(venv)
    task = get_task(POP)
    train, held = train_plants(task).matrix, eval_plants(task).matrix
    seen = set()
    for _ in range(3):
        venv.reset()
        P = batch.system.params_matrix
        assert plant_rows_equal(P, train) == P.shape[0]
        assert plant_rows_equal(P, held) == 0
        seen.update(tuple(r) for r in P)
    assert len(seen) > 1
    opts = batch.options
    assert opts.episode_duration == task.episode_duration
    assert tuple(opts.omega_ref_range) == (task.protocol.targets[0], task.protocol.targets[-1])
    assert venv.observation_space.shape[0] == 2 * 8 + 1  # the motor observation: 8 increments, 8 voltages, target
    venv.close()


def test_a_base_entry_takes_the_tasks_options_and_the_user_may_set_only_free_ones():
    hp = _settings(POP, "ppo", None, 10, 2, None, {})
    kw = hp["env_kwargs"]
    assert hp["hyperparams_entry"] == "drillgym/Torsional-v0"
    assert kw["episode_duration"] == 60.0 and tuple(kw["omega_ref_range"]) == (0.5, 8.0)
    assert "randomize" not in kw and kw["observation"] == "motor"
    assert (
        _settings(POP, "ppo", None, 10, 2, None, {"env_kwargs": {"motor_history": 32}})["env_kwargs"]["motor_history"]
        == 32
    )
    with pytest.raises(InputError, match="fixes env option 'episode_duration'"):
        _settings(POP, "ppo", None, 10, 2, None, {"env_kwargs": {"episode_duration": 45.0}})
    with pytest.raises(InputError, match="fixes env option 'observation'"):
        _settings(POP, "ppo", "full", 10, 2, None, {})
    with pytest.raises(InputError, match="fixes its plants; the hyperparameter population"):
        _settings(POP, "ppo", None, 10, 2, None, {"population": "default"})


def test_task_env_kwargs_accepts_the_tasks_own_values_and_refuses_others():
    task = get_task("drillgym/Nominal-TwoEncoder-v0")
    kw = task_env_kwargs(task, {"observation": "sensors", "omega_ref_range": [0.5, 8.0], "reward": {"track": 1.0}})
    assert kw["observation"] == "sensors" and kw["reward"] == {"track": 1.0}
    with pytest.raises(InputError, match="fixes env option 'omega_ref_range'"):
        task_env_kwargs(task, {"omega_ref_range": [2.0, 8.0]})
    with pytest.raises(InputError, match="fixes env option 'randomize'"):
        task_env_kwargs(task, {"randomize": 0.2})
    assert "randomize" not in task_env_kwargs(task, {"randomize": 0.2}, from_base_entry=True)


def test_train_cli_refuses_effects_on_a_task_in_one_line(tmp_path):
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "drillgym.cli",
            "train",
            "--env",
            POP,
            "--add-effect",
            "motor_lag",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode != 0
    lines = [ln for ln in r.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and "fixes its plants" in lines[0]
    assert not (tmp_path / "o" / "model.zip").exists()
