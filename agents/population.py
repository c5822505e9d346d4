"""Domain randomisation over the plant population of the robust-control evaluation (training only).

:class:`PopulationRandomizer` draws each new episode's rig from an uncertainty set
(:mod:`controllers.evaluation.population`, default ``controllers/evaluation/plants.yaml``): relative
ranges of the base parameters, uniform ranges of the effect parameters (motor lag ``tau_m``, input
delay ``delay``) and the position-dependent brake friction's harmonic (amplitude and phase).  The
encoder part of the set (counts, angle noise) is not drawn: the training env's encoder is one for all
rigs.  :func:`use_population` installs it in a drillgym SB3 VecEnv built with
:func:`population_env_kwargs` (the set's effects added to the env's model).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from drillgym.errors import InputError

from .batch import episode_batch

__all__ = ["PopulationRandomizer", "population_env_kwargs", "use_population"]


def _uncertainty(population: str | Path | None):
    from controllers.evaluation.population import load_uncertainty

    return load_uncertainty(None if population in (None, "default", True) else population)


def population_env_kwargs(env_kwargs: dict[str, Any], population: str | Path | None) -> dict[str, Any]:
    """Environment options whose model holds the uncertainty set's effects.

    Parameters
    ----------
    env_kwargs : dict
        Options of the environment (:class:`drillgym.envs.EnvOptions`).
    population : str or pathlib.Path or None
        The uncertainty set: ``"default"`` (or None) or a YAML path.

    Returns
    -------
    dict
        A copy of ``env_kwargs`` with the set's effects (motor lag, delay, position friction) added
        to ``effects`` and the env's own randomisation removed.  A ``model`` option (a
        :class:`drillgym.Model` or a model file's path) is the nominal model: it becomes ``params``,
        ``effects`` and ``effect_params`` (its other effects keep their values in every plant).
    """
    us = _uncertainty(population)
    kw = dict(env_kwargs)
    if kw.get("model") is not None:
        from drillgym.model import model_arguments

        m_params, comp, values = model_arguments(
            kw.pop("model"), kw.get("params"), kw.get("effects"), kw.get("effect_params"), "env option 'model'"
        )
        kw.update(params=m_params, effects=comp.specs(), effect_params=values)
    effects = list(kw.get("effects") or [])
    kw["effects"] = effects + [e for e in us.effect_names() if e not in effects]
    kw.pop("randomize", None)
    kw.pop("randomize_names", None)
    return kw


class PopulationRandomizer:
    """Per-episode parameter rows drawn from an uncertainty set (the env's ``ParameterRandomizer`` role).

    Parameters
    ----------
    composition : Composition
        The env's model; it must hold the set's effects.
    base : RigParams
        The nominal base parameters.
    population : str or pathlib.Path, optional
        The uncertainty set: ``"default"`` (or None) or a YAML path.
    nominal_fraction : float, optional
        Probability (0-1) that an episode's rig is the nominal one instead (base parameters
        nominal, every effect of the set at its lower bound, no position friction).
    nominal_below : float, optional
        Episodes whose target is below this speed (rad/s) always run the nominal rig.
    values : mapping of str to float, optional
        The nominal values of the model's effect parameters the set does not draw (default: each
        parameter's own).

    Raises
    ------
    InputError
        ``nominal_fraction`` outside [0, 1], ``nominal_below`` negative, or the model lacks the
        set's effects.

    Notes
    -----
    The plants are drawn only for targets where the rig's slip equilibrium can be held without
    damping the brake's negative slope, e.g. from the second Hopf point (2.83 rad/s nominal) up:
    there the teacher's labels hold on every plant, and below it no motor-side law damps every
    plant (:mod:`controllers.limits`).
    """

    active = True

    def __init__(
        self,
        composition,
        base,
        population: str | Path | None = None,
        nominal_fraction: float = 0.0,
        nominal_below: float = 0.0,
        values=None,
    ) -> None:
        if not (0.0 <= nominal_fraction <= 1.0):
            raise InputError(f"nominal_fraction must be in [0, 1], got {nominal_fraction!r}")
        if not (np.isfinite(nominal_below) and nominal_below >= 0.0):
            raise InputError(f"nominal_below must be a speed >= 0 (rad/s), got {nominal_below!r}")
        self.nominal_fraction, self.nominal_below = float(nominal_fraction), float(nominal_below)
        self.us = _uncertainty(population)
        missing = [e for e in self.us.effect_names() if e not in set(composition.names)]
        if missing:
            raise InputError(
                f"the env's model lacks the population's effects {missing}; build it with population_env_kwargs"
            )
        self.composition, self.base = composition, base
        self.values = dict(values or {})

    def sample(self, rng: np.random.Generator, omega_ref: float | None = None) -> np.ndarray:
        """One parameter vector for an episode.

        Parameters
        ----------
        rng : numpy.random.Generator
            The episode's random generator.
        omega_ref : float, optional
            The episode's target speed (rad/s).

        Returns
        -------
        numpy.ndarray
            The parameters in the composition's layout.
        """
        us = self.us
        low = omega_ref is not None and omega_ref < self.nominal_below
        if low or (self.nominal_fraction > 0 and rng.random() < self.nominal_fraction):
            values = {**self.values, **{k: float(lo) for k, (lo, hi) in us.effects.items()}}
            values.update({n: 0.0 for pair in us.harmonics for n in pair})
            return self.composition.vector(self.base, values)
        scaled = {k: getattr(self.base, k) * (1.0 + rng.uniform(-r, r)) for k, r in us.relative.items()}
        values = {**self.values, **{k: float(rng.uniform(lo, hi)) for k, (lo, hi) in us.effects.items()}}
        for (cn, sn), amax in us.harmonics.items():
            a, phi = rng.uniform(0.0, amax), rng.uniform(0.0, 2 * np.pi)
            values[cn], values[sn] = float(a * np.cos(phi)), float(a * np.sin(phi))
        return self.composition.vector(self.base.replace(**scaled), values)


def use_population(
    venv, population: str | Path | None = None, nominal_fraction: float = 0.0, nominal_below: float = 0.0
) -> None:
    """Draw every later episode's rig of a drillgym SB3 VecEnv from an uncertainty set.

    Parameters
    ----------
    venv : stable_baselines3.common.vec_env.VecEnv
        A VecEnv built with :func:`population_env_kwargs` options, or a wrapper of one.
    population : str or pathlib.Path, optional
        The uncertainty set: ``"default"`` (or None) or a YAML path.
    nominal_fraction : float, optional
        Probability of the nominal rig.
    nominal_below : float, optional
        Targets below this speed (rad/s) get the nominal rig.
    """
    batch = episode_batch(venv)
    batch.randomizer = PopulationRandomizer(
        batch.system.composition,
        batch.options.rig_params,
        population,
        nominal_fraction,
        nominal_below,
        values=batch.options.effect_params,
    )
