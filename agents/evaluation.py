"""Evaluation of a trained agent as the controllers are evaluated: the lowest held target from rest.

A target counts as *held* when, over the last ``window`` seconds of a ``duration``-second run from rest
on the simulated rig (the harness of :mod:`controllers.evaluation`, encoders quantized as on the rig),
the stick-slip severity is below 0.1 and the mean lower-disc speed within 10 % of the target
(:func:`controllers.evaluation.metrics.lowest_free_speed`).  The *lowest held target* (rad/s) is the
lowest target of the grid from which every higher one is held (NaN when the highest is not held).

    >>> from agents.evaluation import lowest_held_target
    >>> lowest_held_target("agents/policies/torsional_motor_learned_nominal/policy.npz")
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

__all__ = ["TARGETS", "evaluate_policy_targets", "lowest_held_target"]

#: target grid (rad/s) of the held-target evaluation: 1.5 ... 8.0 in 0.5 steps
TARGETS = tuple(float(v) for v in np.arange(1.5, 8.01, 0.5))


def evaluate_policy_targets(policy: str | Path, targets: Sequence[float] = TARGETS, *, config: str = "torsional",
                            duration: float = 60.0, window: float = 20.0, seed: int = 0,
                            effects: Any = None, effect_params: dict | None = None) -> list[dict]:
    """One row of harness metrics per target (ssi, offset, tracking_rms, u_peak, ...) of the agent at
    ``policy`` (policy.npz, model.zip or a run directory) started from rest; times in s."""
    from controllers.evaluation.harness import run_job
    from controllers.evaluation.scenarios import SCENARIOS

    return run_job(f"agent:{Path(policy)}", config, SCENARIOS["rest"], list(targets), duration=duration,
                   window=window, seed=seed, effects=effects, effect_params=effect_params)


def lowest_held_target(policy: str | Path, targets: Sequence[float] = TARGETS, **kw: Any) -> float:
    """Lowest held target from rest (rad/s; NaN: not even the highest target held); options as
    :func:`evaluate_policy_targets`."""
    from controllers.evaluation.metrics import lowest_free_speed

    rows = evaluate_policy_targets(policy, targets, **kw)
    t = np.array([r["omega_ref"] for r in rows])
    return lowest_free_speed(t, np.array([r["ssi"] for r in rows]), offset=np.array([r["offset"] for r in rows]))
