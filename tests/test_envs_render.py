"""Rendering: the discs from above and the strip chart, as an RGB array or a (headless) window."""

from __future__ import annotations

import gymnasium as gym
import matplotlib
import numpy as np
import pytest

import drillgym  # noqa: F401
from drillgym.envs import TorsionalEnv, make_vec


@pytest.mark.parametrize("env_id", ["drillgym/Torsional-v0", "drillgym/Coupled-v0"])
def test_rgb_array_render(env_id: str) -> None:
    env = gym.make(env_id, normalize_action=False, render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(50):
        env.step(np.array([2.0], dtype=np.float32))
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert img.shape[0] > 100 and img.shape[1] > 200
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10  # drawn, not blank
    renderer = env.unwrapped._renderer
    assert len(renderer.t) == 51  # reset + 50 steps in the strip chart
    env.close()


def test_human_render_returns_none(monkeypatch) -> None:
    matplotlib.use("Agg")  # headless: the 'window' is an Agg figure
    env = gym.make("drillgym/Torsional-v0", normalize_action=False, render_mode="human")
    env.reset(seed=0)
    assert env.render() is None
    env.step(np.array([1.0], dtype=np.float32))
    env.close()


def test_vector_env_renders_first_rig_and_rejects_bad_mode() -> None:
    venv = make_vec("drillgym/Torsional-v0", 2, normalize_action=False, render_mode="rgb_array")
    venv.reset(seed=0)
    venv.step(np.ones(2))
    assert venv.render().ndim == 3
    with pytest.raises(ValueError, match="render_mode"):
        TorsionalEnv(render_mode="video")
