"""Env rough edges: pickling, clear errors for malformed actions, 'human' rendering without a display,
RecordVideo's optional dependency declared."""

import pickle
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import drillgym  # noqa: F401 - registers the envs

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("env_id", ["drillgym/Torsional-v0", "drillgym/Coupled-v0"])
def test_env_pickles_and_continues_identically(env_id):
    env = gym.make(env_id, normalize_action=False, observation="motor")
    env.reset(seed=3)
    for _ in range(5):
        env.step(np.array([2.0], dtype=np.float32))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        a, b = env.step(np.array([2.5], dtype=np.float32)), clone.step(np.array([2.5], dtype=np.float32))
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1] == b[1]
    assert pickle.loads(pickle.dumps(env.spec)).vector_entry_point(num_envs=2).num_envs == 2


@pytest.mark.parametrize(
    "action, error, words",
    [
        (np.zeros((1, 1)), ValueError, "got shape (1, 1)"),
        (np.zeros(2), ValueError, "got shape (2,)"),
        ("2.0", TypeError, "got str '2.0'"),
        ("abc", TypeError, "got str 'abc'"),
        (None, TypeError, "got NoneType None"),
        (True, TypeError, "got bool True"),
        ([object()], TypeError, "of dtype object"),
        (np.array([np.nan]), ValueError, "must be finite"),
    ],
)
def test_malformed_actions_say_what_is_expected(action, error, words):
    env = gym.make("drillgym/Torsional-v0", normalize_action=False).unwrapped
    env.reset(seed=0)
    with pytest.raises(error) as exc:
        env.step(action)
    msg = str(exc.value)
    assert words in msg and "\n" not in msg, msg
    if "finite" not in words:
        assert "shape (1,)" in msg and "Box(-5, 5, (1,), float32)" in msg, msg


def test_accepted_action_forms():
    env = gym.make("drillgym/Torsional-v0", normalize_action=False).unwrapped
    env.reset(seed=0)
    for a in (np.array([2.0], dtype=np.float32), [2.0], 2.0, 2, np.float64(2.0), np.array(2.0), (2.0,)):
        assert env.step(a)[4]["voltage"] == 2.0


def test_human_render_without_display_warns_once():
    assert "agg" in __import__("matplotlib").get_backend().lower()  # tests run headless (conftest: MPLBACKEND=Agg)
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, render_mode="human")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env.reset(seed=0)
        for _ in range(3):
            env.step(np.array([1.0], dtype=np.float32))
    msgs = [str(w.message) for w in caught if "render_mode='human'" in str(w.message)]
    assert len(msgs) == 1 and "cannot open a window" in msgs[0] and "rgb_array" in msgs[0]
    env.close()


def test_record_video_dependency_is_declared_and_documented():
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert any(d.startswith("moviepy") for d in extras["video"])
    page = (ROOT / "docs" / "environments.md").read_text()
    assert "pip install -e '.[video]'" in page and "RecordVideo" in page
