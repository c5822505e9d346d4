"""Training-only data shaping of DAgger: the low-target curriculum (which targets the episodes get, nothing else)
and the per-episode action offsets."""

from __future__ import annotations

import numpy as np
import pytest

import drillgym  # noqa: F401
from agents.curriculum import LowTargets
from agents.envs import episode_batch
from drillgym.envs.sb3 import make_sb3_vec
from drillgym.errors import InputError


def _targets(curriculum: LowTargets | None, n: int = 64, resets: int = 3) -> np.ndarray:
    venv = make_sb3_vec("drillgym/Torsional-v0", n, observation="motor", episode_duration=0.05)
    venv.seed(5)
    batch = episode_batch(venv)
    if curriculum is not None:
        curriculum.install(batch)
    out = []
    for _ in range(resets):
        obs = venv.reset()
        assert np.allclose(obs[:, -1], batch.omega_ref)  # the observation's target is the drawn one
        out.append(batch.omega_ref.copy())
    return np.concatenate(out)


def test_low_targets_redraw_that_fraction_of_the_episodes_below_the_speed() -> None:
    plain = _targets(None)
    assert plain.min() >= 1.0 and (plain >= 2.5).mean() > 0.6  # the env's U(1, 8)
    every = _targets(LowTargets(fraction=1.0, below=2.5))
    assert every.min() >= 1.0 and every.max() < 2.5 and every.std() > 0.4
    half = _targets(LowTargets(fraction=0.5, below=2.5))
    assert 0.45 < (half < 2.5).mean() < 0.8  # 0.5 + 0.5 * 1.5 / 7 expected


def test_low_targets_refuse_bad_settings() -> None:
    assert LowTargets.from_config(None) is None
    assert LowTargets.from_config({"fraction": 0.3, "below": 2.5}) == LowTargets(0.3, 2.5)
    with pytest.raises(InputError, match="fraction"):
        LowTargets(1.5, 2.5)
    with pytest.raises(InputError, match="expected a mapping"):
        LowTargets.from_config({"fraction": 0.3})
    with pytest.raises(InputError, match="needs drawn targets with 9.0"):
        _targets(LowTargets(0.5, 9.0), n=2, resets=1)  # above the range's top: not a low target


def test_dagger_offsets_are_constant_per_rig_and_episode_and_redrawn_at_its_end(monkeypatch) -> None:
    from stable_baselines3 import PPO

    import agents.distill as distill_module
    from agents.distill import Teacher, distill

    applied = []
    teacher = Teacher(lambda obs: np.zeros(len(obs)), lambda index, obs: None, lambda a: applied.append(a.copy()))
    monkeypatch.setattr(distill_module, "_teacher", lambda *args, **kw: teacher)
    kw = {"observation": "motor", "motor_history": 2, "episode_duration": 0.1}
    model = PPO(
        "MlpPolicy", make_sb3_vec("drillgym/Torsional-v0", 6, normalize_action=True, **kw), n_steps=8, batch_size=48
    )
    distill(model, "drillgym/Torsional-v0", kw, "flatness", n_envs=6, iterations=1, steps=25, beta=1.0, bias=0.2)
    a = np.array(applied)  # (periods, rigs): the teacher's 0 plus each rig's offset
    assert np.ptp(a[:10], axis=0).max() == 0 and np.ptp(a[10:20], axis=0).max() == 0  # constant in an episode
    assert np.all(a[10] != a[9]) and 0.05 < a[:10].std() < 0.5  # redrawn when the 10-period episodes end
    base = []
    teacher2 = Teacher(teacher.actions, teacher.reset, lambda a: base.append(a.copy()))
    monkeypatch.setattr(distill_module, "_teacher", lambda *args, **kw: teacher2)
    distill(model, "drillgym/Torsional-v0", kw, "flatness", n_envs=6, iterations=1, steps=5, beta=1.0)
    assert not np.any(base)  # no offset by default
