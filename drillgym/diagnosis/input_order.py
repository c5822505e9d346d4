"""The order of two Input effects on the signal path, tried both ways.

Input effects act on the voltage one after the other, the first nearest the command
(:meth:`drillgym.effects.Composition.signal_path`): a dead zone before a motor lag is not the same motor as a
lag before a dead zone.  When the model diagnosed holds two Input effects (the model's own and the selected),
:func:`input_order` fits the final model again in its order and with the two swapped (the selected effects'
parameters, and the base parameters when the diagnosis freed them, with the segments' start speeds), and
reports the better with the score difference N_eff ln(RSS_worse / RSS_better).  Delays need no such check:
a delay commutes with every time-invariant Input effect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..effects import Composition
from ..effects.base import Input
from .context import SelectionContext, converged_fit
from .effective import effective_samples
from .effects import label_effects
from .results import Diagnosis
from .state import Screening, transfer

__all__ = ["InputOrder", "input_order", "ORDER_TIE_NATS"]

#: orders whose scores differ by less are reported as a tie: the data do not tell them apart
ORDER_TIE_NATS = 2.0
#: least-squares evaluations of each order's refit
MAX_NFEV = 15


@dataclass
class InputOrder:
    """Two Input effects' order, fitted both ways.

    Attributes
    ----------
    diagnosed, swapped : list of str
        The signal path (command side first) as diagnosed, and with the two Input effects swapped.
    rss_diagnosed, rss_swapped : float
        Residual sum of squares of each order's refit (the selection's units).
    n_eff : float
        Effectively independent residual samples the score counts.
    """

    diagnosed: list[str]
    swapped: list[str]
    rss_diagnosed: float
    rss_swapped: float
    n_eff: float

    @property
    def score_gap_nats(self) -> float:
        """N_eff ln(RSS of the worse order / RSS of the better) (nats; 0 on a tie of the RSS)."""
        lo, hi = sorted((self.rss_diagnosed, self.rss_swapped))
        return self.n_eff * math.log(hi / lo) if lo > 0 else math.inf

    @property
    def better(self) -> list[str]:
        """The order with the lower RSS (the diagnosed one on equal RSS)."""
        return self.swapped if self.rss_swapped < self.rss_diagnosed else self.diagnosed

    @property
    def tie(self) -> bool:
        """Whether the data cannot tell the orders apart (:data:`ORDER_TIE_NATS`)."""
        return self.score_gap_nats < ORDER_TIE_NATS

    def to_json(self) -> dict:
        """``{diagnosed, swapped, better, score_gap_nats, tie, rss_diagnosed, rss_swapped}``."""
        return {
            "diagnosed": self.diagnosed,
            "swapped": self.swapped,
            "better": self.better,
            "score_gap_nats": round(self.score_gap_nats, 3),
            "tie": self.tie,
            "rss_diagnosed": self.rss_diagnosed,
            "rss_swapped": self.rss_swapped,
        }

    def line(self) -> str:
        """The decision in words."""
        path = " -> ".join(self.better)
        if self.tie:
            return (
                f"order of the Input effects: {' -> '.join(self.diagnosed)} and {' -> '.join(self.swapped)} fit "
                f"alike (scores {self.score_gap_nats:.1f} nats apart): the data do not tell the order"
            )
        which = "as diagnosed" if self.better is self.diagnosed else "swapped"
        return (
            f"order of the Input effects (command side first): {path} ({which}) fits better by "
            f"{self.score_gap_nats:.1f} nats; give --add-effect in that order"
        )


def input_order(screening: Screening, diagnosis: Diagnosis) -> InputOrder | None:
    """The final model refitted with its two Input effects in both orders (see the module docstring).

    Parameters
    ----------
    screening : Screening
        The recording screened (its search model's objective and scales as the selection left them).
    diagnosis : Diagnosis
        The diagnosis (its composition, final vector and selected effects).

    Returns
    -------
    InputOrder or None
        Both orders' fits, or None when the model diagnosed has not exactly two Input effects.
    """
    comp, vec = diagnosis.composition, diagnosis.vector
    if comp is None or vec is None:
        return None
    active = [*label_effects(diagnosis.model), *diagnosis.selected]
    inputs = [e.name for e in comp.effects if issubclass(e, Input) and e.name in active]
    if len(inputs) != 2:
        return None
    effects = list(comp.effects)
    i, j = (next(k for k, e in enumerate(effects) if e.name == n) for n in inputs)
    effects[i], effects[j] = effects[j], effects[i]
    other = Composition(tuple(effects))
    model = screening.model
    free = [p.name for e in comp.effects if e.name in diagnosis.selected for p in e.parameters]
    base_names = tuple(model.base_names) if diagnosis.base_off else ()
    fits = []
    for c in (comp, other):
        obj = model.obj.with_own_speeds()
        if c is not comp:
            obj.model = obj.model.with_composition(c)
        start = transfer(vec, comp, c)
        ctx = SelectionContext(obj, c, start, transfer(model.nominal, comp, c), base_names, {})
        fits.append(converged_fit(ctx, start, [*free, *base_names], MAX_NFEV))
    r = fits[0].residual
    n_eff = effective_samples(r, model.obj.block_ids) if r is not None and len(r) else float(len(model.obj.block_ids))
    return InputOrder(
        comp.signal_path(among=active),
        other.signal_path(among=active),
        float(fits[0].rss_after),
        float(fits[1].rss_after),
        float(n_eff),
    )
