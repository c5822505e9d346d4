"""Evaluation scenarios: start, plant mismatch and measurement chain.

Every scenario is run for each target speed of the grid (default 0.5-8 rad/s
in 0.5 rad/s steps) in each configuration.  The controllers are always built
on the identified parameters; a scenario may change the plant (friction +-20 %),
the sensors (encoder resolution, angle noise), or run a population of plants drawn
from an uncertainty set (``plants``, :mod:`.population`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym import RigParams, simulate_batch
from drillgym.equilibria import equilibrium_voltage
from drillgym.errors import InputError
from drillgym.measurement import DEFAULT_COUNTS_PER_REV

__all__ = ["Scenario", "SCENARIOS", "DEFAULT_TARGETS", "parse_scenarios", "plant_params", "cycle_states"]

DEFAULT_TARGETS = np.round(np.arange(0.5, 8.0 + 1e-9, 0.5), 3)
CYCLE_SETTLE = 40.0  # s of open loop to develop the stick-slip cycle


@dataclass(frozen=True)
class Scenario:
    """How a closed-loop run of the harness starts and what plant and encoders it has.

    Parameters
    ----------
    name : str
        Name of the scenario (reports, ``--scenarios``).
    start : str, optional
        ``"rest"`` (default) or ``"cycle"`` (a developed open-loop stick-slip cycle).
    friction_scale : float, optional
        Factor on the brake's Ts, Tc and bb of the plant (the controllers keep the nominal law).
    counts_per_rev : int, optional
        Encoder resolution (counts per revolution).  Default 8000.
    angle_noise : float, optional
        White noise on the measured angles (rad, standard deviation).
    population : bool, optional
        The plant is a population drawn from an uncertainty set (:mod:`.population`), encoders included.
    """

    name: str
    start: str = "rest"
    friction_scale: float = 1.0
    counts_per_rev: int = DEFAULT_COUNTS_PER_REV
    angle_noise: float = 0.0
    population: bool = False


SCENARIOS = {
    s.name: s
    for s in (
        Scenario("rest"),
        Scenario("cycle", start="cycle"),
        Scenario("friction-20", friction_scale=0.8),
        Scenario("friction+20", friction_scale=1.2),
        Scenario("noisy", counts_per_rev=2048, angle_noise=1e-3),
        Scenario("plants", population=True),
    )
}


def parse_scenarios(names: str) -> list[Scenario]:
    """Comma-separated scenario names -> scenarios (an InputError names an unknown one)."""
    out = []
    for n in [s.strip() for s in names.split(",") if s.strip()]:
        if n not in SCENARIOS:
            raise InputError(f"unknown scenario {n!r}; choose from {', '.join(SCENARIOS)}")
        out.append(SCENARIOS[n])
    if not out:
        raise InputError("no scenario given")
    return out


def plant_params(s: Scenario, params: RigParams | None = None) -> RigParams:
    """The plant of the scenario (friction mismatch applied to the brake law)."""
    p = params or RigParams()
    f = s.friction_scale
    return p if f == 1.0 else p.scaled(Ts=f, Tc=f, bb=f)


def cycle_states(
    config: str,
    targets: np.ndarray,
    params: RigParams,
    u_fold: float,
    *,
    effects: Any = None,
    effect_params: Mapping[str, float] | None = None,
) -> np.ndarray:
    """States (n, n_state) on a developed open-loop stick-slip cycle of the plant (base ``params`` and
    its ``effects``) for each target: the cycle at the target's equilibrium voltage of the base model,
    held below the second fold ``u_fold`` (V) so that the cycle exists."""
    u = np.clip(equilibrium_voltage(config, np.asarray(targets, dtype=float), params), 0.5, u_fold - 0.2)
    batch = simulate_batch(
        config, u, CYCLE_SETTLE, params=params, record_every=100, effects=effects, effect_params=effect_params
    )
    return np.stack([batch[k].final_state for k in range(len(u))])
