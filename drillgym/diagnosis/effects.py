"""Which effects the diagnosis tries, and how it fits one: a thin layer over :mod:`drillgym.effects`.

The effects themselves (physics, parameters with unit, bounds, guess and scale, residual
signature, the configurations they act in, what a recording ``needs`` to show them) live in
the effect classes: the library's (:data:`drillgym.effects.LIBRARY`), an installed
package's, or a user's file.  Here: the candidates for a configuration, the composition a
candidate is tried in (the model so far plus the candidate), and the candidate's fit
variables (its own parameters, from its :class:`~drillgym.effects.Parameter` s).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..configurations import Configuration
from ..effects import LIBRARY, Composition, Effect, EffectError, resolve_effect
from ..identification.fitting import FitVariable

__all__ = ["EFFECTS", "get_effect", "effects_for", "applies_to", "with_candidate", "fit_variables", "label_effects"]

#: the library, by name (the diagnosis' default candidates)
EFFECTS: dict[str, type[Effect]] = dict(LIBRARY)


def label_effects(label: str) -> list[str]:
    """The effects of a model's label (:attr:`drillgym.effects.Composition.label`: ``"base"``, or the names joined
    by ``+``), in order; empty for the base model.

    Parameters
    ----------
    label : str
        The label.

    Returns
    -------
    list of str
        The effects' names.
    """
    return [] if label == "base" else label.split("+")


def get_effect(spec: str | type[Effect]) -> type[Effect]:
    """An effect class from a name (library, entry point) or ``path/to/file.py:NAME``.

    Parameters
    ----------
    spec : str or Effect class
        The name, file spec or class.

    Returns
    -------
    Effect class
        The effect.

    Raises
    ------
    EffectError
        An unknown name or a file that cannot be used (the one-line message lists the known names).
    """
    try:
        obj = resolve_effect(spec)
    except EffectError as exc:
        raise EffectError(str(exc)) from None
    return obj if isinstance(obj, type) else type(obj)


def applies_to(effect: type[Effect], config: Configuration) -> bool:
    """Whether an effect acts in a configuration (its ``configurations`` class attribute).

    Parameters
    ----------
    effect : Effect class
        The effect.
    config : Configuration
        The configuration.

    Returns
    -------
    bool
        Whether it acts there.
    """
    return config.label in effect.configurations


def effects_for(config: Configuration) -> list[type[Effect]]:
    """The library's effects that can act in a configuration.

    Parameters
    ----------
    config : Configuration
        The configuration.

    Returns
    -------
    list of Effect classes
        The effects.
    """
    return [e for e in EFFECTS.values() if applies_to(e, config)]


def with_candidate(model: Composition, candidate: type[Effect]) -> Composition:
    """The composition a candidate is tried in: the model's effects, then the candidate.

    Parameters
    ----------
    model : Composition
        The model.
    candidate : Effect class
        The candidate.

    Returns
    -------
    Composition
        The composition.
    """
    return Composition(tuple(model.effects) + (candidate,))


def fit_variables(
    composition: Composition,
    effect: type[Effect],
    start: np.ndarray | None = None,
    values: dict[str, Any] | None = None,
) -> list[FitVariable]:
    """An effect's parameters as fit variables (bounds, guess and scale from its Parameters).

    Parameters
    ----------
    composition : Composition
        The composition the effect is in.
    effect : Effect class
        The effect.
    start : numpy.ndarray, optional
        A vector of ``composition`` to start from.
    values : dict of str to float, optional
        Starting values by name (before ``start``).

    Returns
    -------
    list of FitVariable
        The variables.
    """
    out = []
    for p in effect.parameters:
        x0 = None
        if values and p.name in values:
            x0 = values[p.name]
        elif start is not None:
            x0 = float(start[composition.param_index(p.name)])
        out.append(FitVariable.of_effect(composition, p.name, x0))
    return out
