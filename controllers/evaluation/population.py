"""A population of plants that differ from the controllers' model: the uncertainty set and its samples.

The controllers are built from the nominal (or identified) parameters; every plant of the
population is drawn from an :class:`UncertaintySet` (default: ``plants.yaml`` beside this module,
documented there): relative ranges of base parameters, uniform ranges of effect parameters
(motor lag, input delay), harmonic pairs of an effect (position-dependent brake friction, amplitude
and phase drawn) and the plant's encoder (counts per revolution, white angle noise) that the
controllers are not told.

    >>> from controllers.evaluation.population import load_uncertainty, sample_plants
    >>> pop = sample_plants(20, seed=0)            # the default set
    >>> pop.columns[3]["km"], pop.matrix.shape     # plant 3's motor constant, (20, n_params)
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from drillgym import RigParams
from drillgym.effects import Composition, compose
from drillgym.errors import InputError
from drillgym.io import describe_parse_error
from drillgym.io.structured import load_yaml
from drillgym.params import PARAM_NAMES

__all__ = ["DEFAULT_UNCERTAINTY", "UncertaintySet", "PlantPopulation", "load_uncertainty", "sample_plants"]

DEFAULT_UNCERTAINTY = Path(__file__).with_name("plants.yaml")
"""The default uncertainty set (YAML, documented in the file)."""

_EFFECT_OF = {
    "tau_m": "motor_lag",
    "delay": "input_delay",
    "pf_c1": "position_friction",
    "pf_s1": "position_friction",
    "pf_c2": "position_friction",
    "pf_s2": "position_friction",
}
_SECTIONS = ("relative", "effects", "harmonics", "encoder")


@dataclass(frozen=True)
class UncertaintySet:
    """What a plant may be (usually read by :func:`load_uncertainty`).

    Parameters
    ----------
    relative : mapping of str to float, optional
        Relative range of base parameters: name -> r, drawn uniformly in value x (1 +- r), 0 <= r < 1.
    effects : mapping of str to tuple of float, optional
        Effect parameters: name -> [lo, hi] (the parameter's unit), drawn uniformly.
    harmonics : mapping of tuple of str to float, optional
        (cos, sin) pairs of effect parameters -> largest amplitude; amplitude and phase are drawn.
    counts_per_rev : tuple of int, optional
        Encoder resolution range [lo, hi] (counts/rev).
    angle_noise : tuple of float, optional
        Angle noise range [lo, hi] (rad, standard deviation).
    source : str, optional
        Where the set comes from, named in error messages.
    """

    relative: Mapping[str, float] = field(default_factory=dict)
    effects: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    harmonics: Mapping[tuple[str, str], float] = field(default_factory=dict)
    counts_per_rev: tuple[int, int] = (8000, 8000)
    angle_noise: tuple[float, float] = (0.0, 0.0)
    source: str = "inline"

    def effect_names(self) -> list[str]:
        """Library effects the population's composition needs (in a fixed order)."""
        names = set(self.effects) | {n for pair in self.harmonics for n in pair}
        order = ["motor_lag", "input_delay", "position_friction"]
        unknown = sorted(n for n in names if n not in _EFFECT_OF)
        if unknown:
            raise InputError(
                f"uncertainty set {self.source}: unknown effect parameter {unknown[0]!r}; "
                f"known: {', '.join(_EFFECT_OF)}"
            )
        return [e for e in order if e in {_EFFECT_OF[n] for n in names}]

    def columns(self) -> list[str]:
        """Names of the per-plant values, in the order of the results' columns."""
        return (
            list(self.relative)
            + list(self.effects)
            + [n for pair in self.harmonics for n in pair]
            + ["counts_per_rev", "angle_noise"]
        )


def _pair(v: Any, what: str, source: str) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in v)
    except (TypeError, ValueError):
        raise InputError(f"uncertainty set {source}: {what} must be [lo, hi], got {v!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise InputError(f"uncertainty set {source}: {what} needs finite lo <= hi, got [{lo}, {hi}]")
    return lo, hi


def load_uncertainty(path: str | Path | None = None) -> UncertaintySet:
    """Read an uncertainty set from YAML.

    Parameters
    ----------
    path : str or path, optional
        The YAML file (sections ``relative``, ``effects``, ``harmonics``, ``encoder``); default
        :data:`DEFAULT_UNCERTAINTY` (``plants.yaml``).

    Returns
    -------
    UncertaintySet
        The validated set.

    Raises
    ------
    InputError
        An unreadable file, invalid YAML, an unknown section or parameter, or a bad range; one line.
    """
    import yaml

    path = Path(path) if path is not None else DEFAULT_UNCERTAINTY
    try:
        raw = load_yaml(path.read_text(encoding="utf-8")) or {}
    except OSError as exc:
        raise InputError(f"uncertainty set {path}: cannot read it ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"uncertainty set {path}: not UTF-8 text (byte {exc.start}); give a YAML file") from None
    except yaml.YAMLError as exc:
        raise InputError(f"uncertainty set {path}: not valid YAML ({describe_parse_error(exc)})") from None
    src = str(path)
    if not isinstance(raw, dict) or set(raw) - set(_SECTIONS):
        bad = sorted(set(raw) - set(_SECTIONS)) if isinstance(raw, dict) else [type(raw).__name__]
        raise InputError(f"uncertainty set {src}: unknown section {bad[0]!r}; sections: {', '.join(_SECTIONS)}")
    rel = {}
    for k, v in (raw.get("relative") or {}).items():
        if k not in PARAM_NAMES:
            raise InputError(f"uncertainty set {src}: {k!r} is not a base parameter (RigParams)")
        if not (isinstance(v, (int, float)) and 0 <= v < 1):
            raise InputError(f"uncertainty set {src}: relative range of {k} must be in [0, 1), got {v!r}")
        rel[k] = float(v)
    eff = {k: _pair(v, k, src) for k, v in (raw.get("effects") or {}).items()}
    har = {}
    for k, v in (raw.get("harmonics") or {}).items():
        names = tuple(s.strip() for s in str(k).split(","))
        if len(names) != 2 or not (isinstance(v, (int, float)) and v >= 0):
            raise InputError(
                f"uncertainty set {src}: harmonics entry must be 'cos,sin': max amplitude, got {k!r}: {v!r}"
            )
        har[names] = float(v)
    enc = raw.get("encoder") or {}
    cpr = _pair(enc.get("counts_per_rev", [8000, 8000]), "encoder counts_per_rev", src)
    if cpr[0] < 1:
        raise InputError(f"uncertainty set {src}: encoder counts_per_rev must be >= 1, got {cpr[0]}")
    noise = _pair(enc.get("angle_noise", [0.0, 0.0]), "encoder angle_noise", src)
    if noise[0] < 0:
        raise InputError(f"uncertainty set {src}: encoder angle_noise must be >= 0 rad, got {noise[0]}")
    us = UncertaintySet(rel, eff, har, (int(cpr[0]), int(cpr[1])), noise, src)
    us.effect_names()  # unknown effect parameters fail here
    return us


@dataclass
class PlantPopulation:
    """n plants of one composition: drawn from an uncertainty set (:func:`sample_plants`) or a user's
    (:meth:`.plants_file.PlantSet.population`).

    Parameters
    ----------
    composition : Composition
        The effects the plants share.
    matrix : ndarray
        (n, n_params) parameter matrix in the composition's layout.
    counts_per_rev : ndarray
        Encoder resolution of each plant (counts/rev), (n,).
    angle_noise : ndarray
        Angle noise of each plant (rad), (n,).
    columns : list of dict
        The plants' values by name, one dict per plant (drawn: keys :meth:`UncertaintySet.columns`).
    uncertainty : UncertaintySet or None
        The set they were drawn from (None: plants a user wrote, :mod:`.plants_file`).
    names : list of str, optional
        The plants' names (a plants file's); empty: drawn plants, named by their index.
    """

    composition: Composition
    matrix: np.ndarray
    counts_per_rev: np.ndarray
    angle_noise: np.ndarray
    columns: list[dict[str, float]]
    uncertainty: UncertaintySet | None
    names: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        """Number of plants."""
        return int(self.matrix.shape[0])

    def subset(self, index: np.ndarray | list[int]) -> PlantPopulation:
        """The plants ``index`` (in that order)."""
        i = np.asarray(index, dtype=int)
        return PlantPopulation(
            self.composition,
            self.matrix[i],
            self.counts_per_rev[i],
            self.angle_noise[i],
            [self.columns[k] for k in i],
            self.uncertainty,
            [self.names[k] for k in i] if self.names else [],
        )


def sample_plants(
    n: int, seed: int = 0, uncertainty: UncertaintySet | str | Path | None = None, params: RigParams | None = None
) -> PlantPopulation:
    """Draw n plants around ``params`` from an uncertainty set.

    The same (n, seed, set) always gives the same plants, and the first k plants of a population of
    n > k are the population of k.

    Parameters
    ----------
    n : int
        Number of plants (>= 1).
    seed : int, optional
        Seed of the population.
    uncertainty : UncertaintySet, str or path, optional
        The set, or its YAML file; default ``plants.yaml``.
    params : RigParams, optional
        The nominal base parameters; default the identified set.

    Returns
    -------
    PlantPopulation
        The plants.
    """
    if int(n) != n or n < 1:
        raise InputError(f"the number of plants must be a positive integer, got {n!r}")
    us = uncertainty if isinstance(uncertainty, UncertaintySet) else load_uncertainty(uncertainty)
    base = params or RigParams()
    comp, _ = compose(us.effect_names(), {})
    rows, P, cprs, noises = [], [], [], []
    for k in range(int(n)):
        rng = np.random.default_rng([int(seed), k])  # per plant: plant k does not depend on n
        col: dict[str, float] = {}
        scale = {}
        for name, r in us.relative.items():
            scale[name] = 1.0 + rng.uniform(-r, r)
            col[name] = getattr(base, name) * scale[name]
        values = {}
        for name, (lo, hi) in us.effects.items():
            values[name] = col[name] = float(rng.uniform(lo, hi))
        for (cn, sn), amax in us.harmonics.items():
            a, phi = rng.uniform(0.0, amax), rng.uniform(0.0, 2 * np.pi)
            values[cn] = col[cn] = float(a * np.cos(phi))
            values[sn] = col[sn] = float(a * np.sin(phi))
        cpr = int(rng.integers(us.counts_per_rev[0], us.counts_per_rev[1] + 1))
        noise = float(rng.uniform(*us.angle_noise))
        col["counts_per_rev"], col["angle_noise"] = float(cpr), noise
        P.append(comp.vector(base.replace(**{k_: col[k_] for k_ in us.relative}), values))
        rows.append(col)
        cprs.append(cpr)
        noises.append(noise)
    return PlantPopulation(comp, np.array(P), np.array(cprs), np.array(noises), rows, us)
