"""drillgym.parallel without Ray: the local process pool, ordered results, failures with their inputs."""

import os

import numpy as np
import pytest

from drillgym.parallel import LocalExecutor, TaskFailed, describe_inputs, map_ordered, open_executor, parallelism


def draw(seed: int, n: int) -> float:
    return float(np.random.default_rng(seed).normal(size=n).sum())


def fail_on(x: float, values: np.ndarray) -> float:
    if x == 2:
        raise ValueError(f"x = {x} is refused")
    return x


def die_once(marker: str) -> str:
    """Kills its worker process the first time (no marker yet), returns 'ok' when run again."""
    if not os.path.exists(marker):
        open(marker, "w").close()
        os._exit(3)
    return "ok"


def always_die() -> None:
    os._exit(3)


def test_ordered_results_equal_in_process_and_progress_counts_sizes():
    tasks = [(s, 7) for s in range(7)]
    seen = []
    with LocalExecutor(2) as ex:
        got = map_ordered(ex, draw, tasks, progress=seen.append, sizes=[3] * 7)
    assert got == map_ordered(None, draw, tasks) == [draw(*t) for t in tasks]
    assert sum(seen) == 21 and len(seen) == 7


def test_task_error_names_function_and_inputs():
    with LocalExecutor(2) as ex:
        with pytest.raises(TaskFailed) as e:
            map_ordered(ex, fail_on, [(1, np.arange(3.0)), (2, np.arange(10.0))])
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith("task fail_on(2, array(10,) [0.,1.,2.,3.,...]) failed: ValueError: x = 2 is refused")
    with pytest.raises(TaskFailed, match=r"fail_on\(2, "):  # in this process too
        map_ordered(None, fail_on, [(2, np.zeros(1))])


def test_dead_worker_is_retried_on_a_new_pool(tmp_path):
    with LocalExecutor(2, retries=1) as ex:
        assert map_ordered(ex, die_once, [(str(tmp_path / "m"),)]) == ["ok"]
        assert map_ordered(ex, draw, [(1, 3)]) == [draw(1, 3)]  # the renewed pool keeps working
        with pytest.raises(TaskFailed, match=r"always_die\(\) failed after 2 attempts: its worker process died"):
            ex.submit(always_die).result()


def test_helpers():
    assert open_executor(None, workers=1) is None
    with open_executor(None, workers=2) as ex:
        assert isinstance(ex, LocalExecutor) and parallelism(ex) == 2
    assert parallelism(None) == 1
    assert describe_inputs((list(range(10)),), {"u": "x" * 100}) == "list[10](0, 1, 2, 3, ...), u='" + "x" * 56 + "..."
    with pytest.raises(ValueError, match="workers must be >= 1"):
        LocalExecutor(0)


def square_trial(config: dict) -> dict:
    """A Tune trial's work: returns its config's square and a seeded draw."""
    return {"square": config["x"] ** 2, "draw": draw(config["x"], 3)}


def refuse_one(config: dict) -> int:
    if config["x"] == 1:
        raise ValueError("x = 1 is refused")
    return config["x"]


def test_train_seeds_go_to_ray_tune_trials(tmp_path, monkeypatch):
    """`drillgym train --seeds 2 --ray local` hands one job per seed to drillgym.tune.run_trials (stubbed
    here: the trials themselves are tested in test_parallel_ray.py) and writes the seeds' summary."""
    import csv

    import drillgym.tune
    from drillgym.cli import main

    calls = []

    def fake_run_trials(fn, jobs, *, ray, **kw):
        calls.append((fn.__name__, [j["seed"] for j in jobs], [j["out"] for j in jobs], ray))
        return [
            {"seed": j["seed"], "timesteps": 64, "wall_time": 1.0, "train_time": 1.0, "lowest_held": 8.5} for j in jobs
        ]

    monkeypatch.setattr(drillgym.tune, "run_trials", fake_run_trials)
    with pytest.raises(SystemExit) as ok:
        main(
            [
                "train",
                "--algo",
                "ppo",
                "--timesteps",
                "64",
                "--seeds",
                "2",
                "--seed",
                "3",
                "--ray",
                "local",
                "--eval-every",
                "0",
                "--out",
                str(tmp_path),
            ]
        )
    assert ok.value.code == 0
    assert calls == [("_train_one", [3, 4], [tmp_path / "seed_3", tmp_path / "seed_4"], "local")]
    with open(tmp_path / "results.csv") as f:
        assert [r["seed"] for r in csv.DictReader(f)] == ["3", "4"]


def test_ray_executor_without_a_connection_is_refused():
    import ray

    from drillgym.parallel import RayExecutor, RayUnavailable

    if ray.is_initialized():
        pytest.skip("this process is connected to Ray")
    with pytest.raises(RayUnavailable, match=r"^RayExecutor\(None\) needs a connected Ray"):
        RayExecutor(None)
    assert not ray.is_initialized()
