"""The selection's effects judged again with the discovered candidate in the model.

The selection chose the library's effects without the candidate: beside a large residual of an effect the
library lacks, an effect of the library may be taken for the part of it that it imitates (60 s of ramps with a
0.15 V voltage offset after a 25 ms lag: a friction drift selected).  Once the candidate is fitted
(:mod:`.candidate_fit`), each selected effect is switched off and the candidate's parameters (and the base
parameters its fit freed) fitted again without it, with the segments' start speeds; the effect is scored against
that fit by the selection's own rules (:func:`.scoring.score`, :func:`.scoring.significant`, its parameters
counted).  An effect that no longer counts is reported, not removed: the selected model is what the selection
decided, and the candidate is a hypothesis.  The signal-path effects (lag, delay) are judged beside the candidate
by :mod:`.beside`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects import Effect
from .beside import SIGNAL_PATH
from .candidate_fit import MAX_NFEV, CandidateFitState
from .context import converged_fit
from .results import Diagnosis
from .scoring import score, significant
from .screening import Screening

__all__ = ["Recheck", "recheck_selection"]


@dataclass
class Recheck:
    """The selected effects scored again with the candidate in the model.

    Attributes
    ----------
    scores : dict of str to float
        Each selected effect rechecked -> its score with the candidate in (nats; what the model loses without it).
    dropped : list of str
        The effects among them that no longer count by the selection's rules.
    """

    scores: dict[str, float] = field(default_factory=dict)
    dropped: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        """``{scores, no_longer_counts}``."""
        return {"scores": {k: round(v, 2) for k, v in self.scores.items()}, "no_longer_counts": list(self.dropped)}

    def line(self) -> str:
        """The result in words."""
        scores = ", ".join(f"{k} {v:.1f} nats" for k, v in self.scores.items())
        if not self.dropped:
            return f"  with it in the model, the selected effects still count ({scores})"
        return (
            f"  with it in the model, {', '.join(self.dropped)} no longer "
            f"{'counts' if len(self.dropped) == 1 else 'count'} ({scores}): the selection may have taken "
            f"{'it' if len(self.dropped) == 1 else 'them'} for part of what the candidate explains; fit both ways"
        )


def recheck_selection(screening: Screening, diagnosis: Diagnosis) -> Recheck | None:
    """Score each effect the selection took (but the signal path's) again with the candidate in the model.

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis, with its candidate fitted (:func:`.candidate_fit.choose_candidate`).

    Returns
    -------
    Recheck or None
        None when there is no fitted candidate or no selected effect to recheck.
    """
    cand = diagnosis.candidate
    fit = cand.fit if cand is not None else None
    if fit is None or fit.state is None:
        return None
    own_model = set(diagnosis.model.split("+"))
    by_name = {e.name: e for e in screening.model.candidates}
    names = [n for n in diagnosis.selected if n in by_name and n not in own_model | set(SIGNAL_PATH)]
    if not names:
        return None
    out = Recheck()
    for name in names:
        out.scores[name], counts = _without(fit.state, by_name[name], by_name)
        if not counts:
            out.dropped.append(name)
    return out


def _without(state: CandidateFitState, effect: type[Effect], by_name: dict[str, type[Effect]]) -> tuple[float, bool]:
    """The candidate's fit with ``effect`` switched off and the rest refitted; ``effect``'s score against that
    (nats) and whether it counts."""
    ctx = state.context(state.base_names, by_name)
    obj, start = ctx.obj, ctx.neutralise(np.asarray(state.result.vector), effect.name)
    res = converged_fit(ctx, start, [*state.fitted, *state.base_names], MAX_NFEV)
    with_it, ids = state.result, obj.channel_ids
    sc, _ = score(res.residual, with_it, len(effect.parameters), channels=ids, blocks=obj.block_ids)
    counts = significant(sc, res.rss_after, with_it.rss_after, len(res.residual), res.residual, with_it.residual, ids)
    return sc, counts
