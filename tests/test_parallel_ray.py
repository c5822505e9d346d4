"""drillgym.parallel on Ray: one local Ray instance for the session (2 CPUs); same seeds -> same results.

Every test here runs in one pytest-xdist worker (group 'ray', ``--dist loadgroup`` in the Makefile), so the
suite starts Ray once.
"""

import csv
import math

import numpy as np
import pytest
import test_parallel_local
from test_parallel_local import die_once, draw, fail_on, refuse_one, square_trial

from drillgym.cli import main
from drillgym.parallel import RayExecutor, TaskFailed, connect_ray, map_ordered

pytestmark = pytest.mark.xdist_group("ray")


@pytest.fixture(scope="session")
def ray_executor():
    """One local Ray instance (2 CPUs) for the session, and an executor on it."""
    import ray

    started = connect_ray("local", num_cpus=2)
    ray.cloudpickle.register_pickle_by_value(test_parallel_local)  # the workers cannot import tests/
    ex = RayExecutor(None)
    yield ex
    ex.shutdown()
    if started:
        ray.shutdown()


def _same(a, b) -> bool:
    """Rows equal value by value (NaN equals NaN)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return a == b and type(a) is type(b)


def test_ray_results_ordered_and_equal_to_in_process(ray_executor):
    tasks = [(s, 5) for s in range(6)]
    seen = []
    assert map_ordered(ray_executor, draw, tasks, progress=seen.append) == [draw(*t) for t in tasks]
    assert seen == [1] * 6
    assert ray_executor.workers == 2


def test_ray_task_error_names_inputs_and_dead_worker_is_retried(ray_executor, tmp_path):
    with pytest.raises(
        TaskFailed,
        match=r"^task fail_on\(2, array\(10,\) \[0\.,1\.,2\.,3\.,\.\.\.\]\) failed: "
        r"ValueError: x = 2 is refused$",
    ):
        map_ordered(ray_executor, fail_on, [(1, np.arange(3.0)), (2, np.arange(10.0))])
    assert map_ordered(ray_executor, die_once, [(str(tmp_path / "marker"),)]) == ["ok"]


def test_harness_on_ray_equals_local(ray_executor):
    from controllers.evaluation import evaluate

    kw = dict(targets=[2.0, 7.5], duration=4.0, window=2.0, plants=4, plants_per_job=2, seed=3, progress=False)
    local = evaluate(["baseline"], ["torsional"], ["rest", "plants"], workers=1, **kw)
    on_ray = evaluate(["baseline"], ["torsional"], ["rest", "plants"], executor=ray_executor, **kw)
    assert len(local) == 2 + 4 * 2
    assert _same(local, on_ray)


def test_sweep_on_ray_equals_local(ray_executor):
    from drillgym.bifurcation import sweep_constant

    u = [0.5, 1.5, 2.5, 3.5, 4.5]
    done = []
    on_ray = sweep_constant("torsional", u, duration=6.0, window=2.0, executor=ray_executor, progress=done.append)
    local = sweep_constant("torsional", u, duration=6.0, window=2.0, chunk=2)
    assert sum(done) == 5 and len(done) == 4  # two chunks per worker on 2 CPUs
    np.testing.assert_array_equal(on_ray.stats, local.stats)
    assert on_ray.stats.shape == (5, local.stats.shape[1]) and np.isfinite(on_ray.omega_l_max).all()


@pytest.mark.slow
def test_evaluate_cli_ray_local_equals_local(ray_executor, tmp_path):
    args = [
        "evaluate",
        "--config",
        "torsional",
        "--controllers",
        "baseline,observer",
        "--targets",
        "2,6",
        "--duration",
        "5",
        "--window",
        "2",
    ]
    for name, extra in (("D0", ["--workers", "2"]), ("D1", ["--ray", "local"])):
        with pytest.raises(SystemExit) as ok:
            main(args + extra + ["--out", str(tmp_path / name)])
        assert ok.value.code == 0
    rows = [list(csv.reader(open(tmp_path / d / "results.csv"))) for d in ("D0", "D1")]
    assert len(rows[0]) == 1 + 2 * 2 and rows[0] == rows[1]


def test_ray_auto_without_a_cluster_is_one_line(monkeypatch, tmp_path, capsys):
    """What Ray raises when 'auto' finds no cluster (seen on this machine with none running) becomes one
    line and exit code 2; the session's instance is hidden from connect_ray (a real 'auto' would find it)."""
    import ray

    def no_cluster(address=None, **kw):
        assert address == "auto"
        raise ConnectionError(
            "Could not find any running Ray instance. Please specify the one to connect to by "
            "setting `--address` flag or `RAY_ADDRESS` environment variable."
        )

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", no_cluster)
    with pytest.raises(SystemExit) as e:
        main(
            [
                "evaluate",
                "--config",
                "torsional",
                "--controllers",
                "baseline",
                "--targets",
                "2",
                "--duration",
                "4",
                "--window",
                "2",
                "--ray",
                "auto",
                "--out",
                str(tmp_path / "o"),
            ]
        )
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2 and "\n" not in err
    assert err.endswith(
        "--ray auto: no Ray cluster is running on this machine (start one with `ray start --head`, or use --ray local)"
    )
    assert not (tmp_path / "o").exists()


def test_tune_trials_ordered_equal_and_failures_named(ray_executor, tmp_path):
    from drillgym.tune import run_trials

    configs = [{"x": x} for x in (3, 0, 2)]
    got = run_trials(square_trial, configs, ray=None, storage=tmp_path, progress=False)
    assert got == [square_trial(c) for c in configs]
    with pytest.raises(
        TaskFailed,
        match=r"^task refuse_one\(\{'x': 1\}\) failed after 2 attempts: "
        r"ValueError: x = 1 is refused$",
    ):
        run_trials(refuse_one, [{"x": 0}, {"x": 1}], ray=None, storage=tmp_path, progress=False, retries=1)
