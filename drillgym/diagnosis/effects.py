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

__all__ = ["EFFECTS", "get_effect", "effects_for", "applies_to", "with_candidate", "fit_variables"]

#: the library, by name (the diagnosis' default candidates)
EFFECTS: dict[str, type[Effect]] = dict(LIBRARY)


def get_effect(spec: "str | type[Effect]") -> type[Effect]:
    """An effect class from a name (library, entry point) or ``path/to/file.py:NAME``; a one-line
    error lists the known names."""
    try:
        obj = resolve_effect(spec)
    except EffectError as exc:
        raise ValueError(str(exc)) from None
    return obj if isinstance(obj, type) else type(obj)


def applies_to(effect: type[Effect], config: Configuration) -> bool:
    """Whether an effect acts in a configuration (its ``configurations`` class attribute)."""
    return config.label in effect.configurations


def effects_for(config: Configuration) -> list[type[Effect]]:
    """The library's effects that can act in a configuration."""
    return [e for e in EFFECTS.values() if applies_to(e, config)]


def with_candidate(model: Composition, candidate: type[Effect]) -> Composition:
    """The composition the candidate is tried in: the model's effects, then the candidate."""
    return Composition(tuple(model.effects) + (candidate,))


def fit_variables(composition: Composition, effect: type[Effect], start: np.ndarray | None = None,
                  values: dict[str, Any] | None = None) -> list[FitVariable]:
    """The effect's parameters as fit variables (bounds, guess and scale from its Parameters);
    ``values`` (by name) or the vector ``start`` give other starting values."""
    out = []
    for p in effect.parameters:
        x0 = None
        if values and p.name in values:
            x0 = values[p.name]
        elif start is not None:
            x0 = float(start[composition.param_index(p.name)])
        out.append(FitVariable.of_effect(composition, p.name, x0))
    return out
