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

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["TARGETS", "evaluate_policy_targets", "lowest_held_target"]

#: target grid (rad/s) of the held-target evaluation: 1.5 ... 8.0 in 0.5 steps
TARGETS = tuple(float(v) for v in np.arange(1.5, 8.01, 0.5))


def evaluate_policy_targets(
    policy: str | Path,
    targets: Sequence[float] = TARGETS,
    *,
    config: str = "torsional",
    duration: float = 60.0,
    window: float = 20.0,
    seed: int = 0,
    effects: Any = None,
    effect_params: dict | None = None,
    model: Any = None,
    trust: bool = False,
) -> list[dict]:
    """Run the agent from rest at each target and measure it with the controllers' harness.

    Parameters
    ----------
    policy : str or path
        The agent: ``policy.npz``, a run's ``model.zip`` or a run directory.
    targets : sequence of float, optional
        Target speeds of the lower disc (rad/s).  Default 1.5 to 8 in steps of 0.5.
    config : str, optional
        Rig configuration.  Default ``"torsional"``.
    duration : float, optional
        Length of each run (s).  Default 60.
    window : float, optional
        Steady-state window at the end of each run (s).  Default 20.
    seed : int, optional
        Seed of the measurement noise.
    effects : optional
        Hidden effects of the plant (names, file specs, classes or instances).
    effect_params : dict, optional
        Their parameter values by name.
    model : drillgym.Model, str or path, optional
        The plant's model (:class:`drillgym.Model` or a model file's path): its base parameters and effects;
        refused beside ``effects`` or ``effect_params``.
    trust : bool, optional
        Read a model file's effect files even when untrusted (:meth:`drillgym.Model.load`).

    Returns
    -------
    list of dict
        One row of harness metrics per target (``ssi``, ``offset``, ``tracking_rms`` in rad/s,
        ``u_peak`` in V, ...; :func:`controllers.evaluation.metrics.run_metrics`).
    """
    from controllers.evaluation.harness import run_job
    from controllers.evaluation.scenarios import SCENARIOS

    params = None
    if model is not None:
        from drillgym.configurations import parse_configuration
        from drillgym.model import as_model, model_arguments

        m = as_model(model, trust=trust, who="evaluate_policy_targets(): model")
        rig, effects, effect_params = model_arguments(
            m, None, effects, effect_params, "evaluate_policy_targets()", parse_configuration(config).label
        )
        params = rig.to_dict()
    return run_job(
        f"agent:{Path(policy)}",
        config,
        SCENARIOS["rest"],
        list(targets),
        duration=duration,
        window=window,
        seed=seed,
        effects=effects,
        effect_params=effect_params,
        params=params,
    )


def lowest_held_target(policy: str | Path, targets: Sequence[float] = TARGETS, **kw: Any) -> float:
    """Lowest target the agent holds from rest.

    Parameters
    ----------
    policy : str or path
        The agent: ``policy.npz``, a run's ``model.zip`` or a run directory.
    targets : sequence of float, optional
        Target grid (rad/s).
    **kw
        Options of :func:`evaluate_policy_targets` (``config``, ``duration``, ``window``, ``seed``,
        ``effects``, ``effect_params``, ``model``, ``trust``).

    Returns
    -------
    float
        Lowest held target (rad/s), from which every higher target is held too; NaN when not even the
        highest target is held.
    """
    from controllers.evaluation.metrics import lowest_free_speed

    rows = evaluate_policy_targets(policy, targets, **kw)
    t = np.array([r["omega_ref"] for r in rows])
    return lowest_free_speed(t, np.array([r["ssi"] for r in rows]), offset=np.array([r["offset"] for r in rows]))
