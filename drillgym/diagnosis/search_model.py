"""The search model: one composition holding the model's effects and every candidate, and what it frees.

The search model is one composition that holds the model's own effects and every candidate, each
candidate at its *neutral* values (:func:`neutral_values`: the effect vanishes), so a candidate is
switched on by freeing its parameters: no new composition is compiled per combination, and any set of
effects is one parameter vector.  The base parameters the configuration excites (:data:`BASE_FREE`:
upper part km, Tcu, bu; string ktheta; lower part Jl; brake law Ts, Tc, ws, delta, bb or the bearing's
Tcl, bl; lateral k, b, e) are re-identified (Ju is held: it fixes the scale of the torques).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..configurations import Configuration
from ..effects import Composition, Effect
from ..identification.experiment import Experiment
from ..identification.fitting import Objective
from ..identification.segmented import SegmentedModel
from .effects import label_effects
from .segments import place_segment_starts

__all__ = [
    "BASE_FREE",
    "SELECTION_DT",
    "SearchModel",
    "neutral_values",
    "vanishes_exactly",
    "search_composition",
    "with_candidate",
    "base_free_parameters",
    "selection_model",
    "default_weights",
]

#: simulator step bound (s) of the selection's fits, RK4, the input's samples on step boundaries
#: (:func:`~drillgym.identification.segmented.steps_per_sample`; 4 ms at 500 Hz and 1 kHz, 2.5 ms at 200 Hz).
#: Recordings at 500 Hz and 1 kHz are predicted within 0.04 noise units of RK4 at 0.25 ms, twice as fast as
#: 2 ms steps.  5 ms steps stay within 0.054 noise units at the nominal parameters, but a coupled recording's
#: LVDT skew (lateral dry friction) then scores 11 nats instead of 52 (4 ms) and 92 (2 ms)
SELECTION_DT = 4e-3
_UPPER = ("km", "Tcu", "bu")
_BRAKE = ("Ts", "Tc", "ws", "delta", "bb")
_LATERAL = ("k", "b", "e")
#: base parameters re-identified per configuration (Ju held: it sets the torque scale)
BASE_FREE: dict[Configuration, tuple[str, ...]] = {
    Configuration.UPPER: _UPPER + ("dTcu", "dbu"),
    Configuration.TORSIONAL: _UPPER + ("ktheta", "Jl") + _BRAKE,
    Configuration.COUPLED: _UPPER + ("ktheta", "Jl") + _BRAKE + _LATERAL,
    Configuration.LATERAL: _UPPER + ("ktheta", "Jl", "Tcl", "bl") + _LATERAL,
    Configuration.FREE_VIBRATION: ("Jl", "ktheta", "Tcl", "bl"),
}
#: values at which the library's effects vanish (any other parameter: 0 clipped into its bounds)
_NEUTRAL = {"tau_m": 1e-4}


def neutral_values(effects: Sequence[type[Effect]]) -> dict[str, float]:
    """Parameter values at which each effect is switched off.

    The declared ``Parameter.neutral``, else the nearest value known here (a motor lag of 0.1 ms), else 0
    clipped into the parameter's bounds (a user's candidate must vanish there).

    Parameters
    ----------
    effects : sequence of Effect classes
        The effects.

    Returns
    -------
    dict of str to float
        Parameter name -> its neutral value.
    """
    out = {}
    for e in effects:
        for p in e.parameters:
            v = p.neutral if p.neutral is not None else _NEUTRAL.get(p.name, min(max(0.0, p.lo), p.hi))
            out[p.name] = float(v)
    return out


def vanishes_exactly(effect: type[Effect]) -> bool:
    """Whether an effect adds exactly nothing at its :func:`neutral_values` (a declared ``Parameter.neutral``, or 0
    within every parameter's bounds); a motor lag's 0.1 ms does not.

    Parameters
    ----------
    effect : Effect class
        The effect.

    Returns
    -------
    bool
        True when a run with it at its neutral values equals a run without it.
    """
    return all(p.neutral is not None or (p.name not in _NEUTRAL and p.lo <= 0.0 <= p.hi) for p in effect.parameters)


def search_composition(model: Composition, candidates: Sequence[type[Effect]]) -> Composition:
    """The model's effects, then the candidates not in it.

    A motor lag comes first among the candidates, so that the segmented model applies it exactly to the input.

    Parameters
    ----------
    model : Composition
        The model diagnosed.
    candidates : sequence of Effect classes
        The candidates.

    Returns
    -------
    Composition
        The search model's composition.
    """
    cands = [c for c in candidates if c.name not in model.names]
    cands.sort(key=lambda c: 0 if c.name == "motor_lag" else 1)
    return Composition(tuple(model.effects) + tuple(cands))


def with_candidate(
    search: Composition, model: str, ahead: dict[str, type[Effect]], effect: type[Effect]
) -> Composition:
    """The search model with a candidate, in the order the diagnosis run again with it kept holds them
    (:func:`.reselection.reselection_inputs`): the model's own effects, the library effects fitted ahead of it,
    the candidate, then the other effects of the search model. The candidate is fitted, and the library selected
    again beside it, on one composition: its kernels are compiled once.

    Parameters
    ----------
    search : Composition
        The diagnosis' search model.
    model : str
        The label of the model diagnosed (``"base"`` or its effects joined by ``+``).
    ahead : dict of str to Effect class
        Library effects fitted ahead of the candidate on the signal path.
    effect : Effect class
        The candidate.

    Returns
    -------
    Composition
        The composition.
    """
    own = set(label_effects(model))
    by_name = {e.name: e for e in search.effects}
    first = [e for e in search.effects if e.name in own]
    before = [by_name.get(n, e) for n, e in ahead.items() if n not in own]
    rest = [e for e in search.effects if e.name not in own and e.name not in ahead]
    return Composition((*first, *before, effect, *rest))


def base_free_parameters(config: Configuration, brake_on: bool = True) -> tuple[str, ...]:
    """The base parameters re-identified for a configuration.

    Parameters
    ----------
    config : Configuration
        The recording's configuration.
    brake_on : bool, optional
        Whether the brake presses on the lower disc (torsional and coupled); without it the bearing's
        friction (Tcl, bl) replaces the brake law.  Default True.

    Returns
    -------
    tuple of str
        Base parameter names.
    """
    names = BASE_FREE[config]
    if config in (Configuration.TORSIONAL, Configuration.COUPLED) and not brake_on:
        names = tuple(n for n in names if n not in _BRAKE) + ("Tcl", "bl")
    return names


def selection_model(exps: Sequence[Experiment], segment_s: float | None, comp: Composition) -> SegmentedModel:
    """The segmented simulation the selection fits.

    RK4 with steps of at most :data:`SELECTION_DT` on the input's samples, the segments starting where the
    data say (:func:`.segments.place_segment_starts`).

    Parameters
    ----------
    exps : sequence of Experiment
        The recordings.
    segment_s : float or None
        Multiple-shooting segment length (s); None: one free run.
    comp : Composition
        The model's composition.

    Returns
    -------
    SegmentedModel
        The model.
    """
    model = SegmentedModel(
        list(exps), segment_s, composition=comp, method="rk4", max_dt=SELECTION_DT, input_aligned=True
    )
    if segment_s is not None:
        place_segment_starts(model)
    return model


@dataclass
class SearchModel:
    """The problem the selection solves: the objective, the search composition, its nominal vector,
    the candidates and the base parameters that may be freed.

    Attributes
    ----------
    obj : Objective
        The residual of the search model against the recordings (its channel scales may be rescaled
        per sensor by :func:`.scoring.balance_sensors`).
    comp : Composition
        The search composition (:func:`search_composition`).
    nominal : numpy.ndarray
        The nominal vector: base parameters as given, effects of the model at their values, candidates neutral.
    candidates : list of Effect classes
        The candidates the recordings can show.
    base_names : tuple of str
        The base parameters re-identified (empty: the base is held).
    """

    obj: Objective
    comp: Composition
    nominal: np.ndarray
    candidates: list[type[Effect]]
    base_names: tuple[str, ...]


def default_weights(config: Configuration) -> dict[str, float]:
    """The channels compared per configuration (all weight 1: the residuals are noise-normalised).

    Parameters
    ----------
    config : Configuration
        The configuration.

    Returns
    -------
    dict of str to float
        Channel -> weight.
    """
    if config is Configuration.UPPER:
        return {"theta_u": 1.0}
    if config.lateral_free:
        return {"theta_u": 1.0, "theta_l": 1.0, "x": 1.0, "y": 1.0}
    return {"theta_u": 1.0, "theta_l": 1.0}
