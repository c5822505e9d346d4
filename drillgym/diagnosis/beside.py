"""The library's signal-path effects tried again beside a discovered candidate.

A motor-side effect the library lacks (a dead zone, cogging, a voltage offset) leaves a residual of up to
thousands of noise units.  Beside it a 20-40 ms motor lag changes that residual by a small fraction, and the
forward selection, which scores each library effect against the model *without* the candidate, rarely takes
it: the base parameters or an input delay absorb it (the motor-side benchmark,
``benchmarks/bench_diagnosis_motor.py``, reports how often the selection alone takes it).

Once the candidate's own fit (:mod:`.candidate_fit`) has removed most of the residual, each effect of the
library's signal path that the selection did not take (:data:`SIGNAL_PATH`) is fitted again *with the
candidate in the model*: its parameters, the candidate's and (when the candidate's fit freed them) the base
parameters, with the segments' start speeds, from the best of its search points, once from the candidate's fit
and once from its terms as regressed (the better fit is kept).  Two trials per effect:

* *added* to the model with the candidate, scored against the candidate alone by the selection's own rules
  (:func:`.scoring.score`, :func:`.scoring.significant`);
* *in place of* the signal-path effect the selection took (a delay where a lag was, or the reverse: beside
  a large residual the selection may take the wrong one), the other switched off; a model of the same size,
  so it counts when its score is above the selection's significance (:data:`.scoring.SIGNIFICANCE`): the
  incumbent was chosen by the selection's rules, and a few nats on a residual still above the noise do not
  overturn it (a lag found with a saturation, 29 ms for 30.5 ms hidden, lost 7 nats to a delay).  When the
  selection itself said it could not tell the incumbent from another effect (its note: a lag/delay tie, a
  near-tie of scores), the incumbent has no precedence: the other counts in its place from
  :data:`.scoring.TIE_NATS` on.

Every trial fits the base parameters too (those the candidate's fit freed or, when it held them as the
diagnosis left them, every one the diagnosis may free): a lag beside an offset is absorbed by a motor constant
10 % off until both are fitted together.  A trial whose base parameters end at a bound of their range does not
count (the diagnosis' own rule: something still missing is absorbed there).  The best trial that counts is
reported.  The search model already holds these effects, ahead of the candidate
on the signal path (the command is delayed or lagged, then shaped, as ``--add-effect`` order reads), so nothing
new is compiled.  When two trials of different effects count and score within :data:`.scoring.TIE_NATS`, or
both count on an input too smooth to tell a lag from a delay (the selection's rule, :mod:`.lag_delay`: less than
:data:`.timing.SMOOTH_INPUT_SHARE` of its variance above the upper disc's corner frequency; on ramps the two
shift the response alike, and the better one is decided by the model's error elsewhere), the tie is stated with
the experiment that separates them.  A lag the candidate was found through and fitted with
(:attr:`.candidate_fit.CandidateFit.with_library`) is treated as one the selection took: the delay is tried in its
place, and the lag is reported as selected beside the candidate, with the tie when the delay does as well.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..effects import Effect
from ..identification.fitting import FitResult, Objective
from .candidate_fit import CandidateFitState, change_pct, moved_text
from .context import base_at_bounds, best_effect_start, converged_fit
from .lag_delay import smooth_input_share
from .results import Diagnosis
from .scoring import SEPARATES_LAG_DELAY, SIGNIFICANCE, TIE_NATS, score, significant
from .screening import Screening
from .timing import SMOOTH_INPUT_SHARE
from .unexplained import Unexplained, unexplained

__all__ = ["BesideCandidate", "SIGNAL_PATH", "MIN_CANDIDATE_CUT", "beside_candidate"]

#: the library effects tried again beside a candidate: the ones a motor-side residual hides
SIGNAL_PATH = ("motor_lag", "input_delay")
#: the share of the unexplained variance the candidate's own fit must remove before anything is tried beside it
MIN_CANDIDATE_CUT = 0.5
#: least-squares evaluations of each fit beside the candidate
MAX_NFEV = 20


@dataclass
class BesideCandidate:
    """The library's signal-path effects fitted beside the candidate.

    Attributes
    ----------
    selected : str or None
        The effect that counts beside the candidate, or the one the candidate was fitted with (its terms found
        through it: :attr:`.candidate_fit.CandidateFit.with_library`) when no trial beats that one (None: none).
    replaces : str or None
        The signal-path effect of the diagnosis that ``selected`` takes the place of (None: added).
    scores : dict of str to float
        Every trial (``NAME`` added, ``NAME for OTHER`` in place of it) -> its score against the candidate
        alone (nats).
    values : dict of str to float
        The selected effect's fitted parameters (its units; empty when none).
    candidate_values : dict of str to float
        The candidate's parameters refitted with it (empty when none).
    after : Unexplained or None
        The residual against the noise with the candidate and the selected effect (None when none).
    tie_with : str or None
        Another effect whose trial counts too and scores within :data:`.scoring.TIE_NATS`.
    base_change_pct : dict of str to float
        The base parameters fitted with them -> their change from nominal (%).
    better_at_bound : str or None
        An effect that fits better in the selected one's place, or above the significance when none is selected,
        but only with a base parameter at a bound of its range, so does not count (said, not hidden).
    """

    selected: str | None
    replaces: str | None = None
    scores: dict[str, float] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)
    candidate_values: dict[str, float] = field(default_factory=dict)
    after: Unexplained | None = None
    tie_with: str | None = None
    base_change_pct: dict[str, float] = field(default_factory=dict)
    better_at_bound: str | None = None

    def to_json(self) -> dict:
        """``{selected, replaces, scores, values, candidate_values, ratio_after, verdict_after, tie_with,
        base_change_pct, better_at_bound, alike_below_significance}``."""
        return {
            "selected": self.selected,
            "replaces": self.replaces,
            "scores": {k: round(v, 2) for k, v in self.scores.items()},
            "values": self.values,
            "candidate_values": self.candidate_values,
            "ratio_after": self.after.ratio_to_noise if self.after is not None else None,
            "verdict_after": self.after.verdict if self.after is not None else None,
            "tie_with": self.tie_with,
            "base_change_pct": {k: round(v, 3) for k, v in self.base_change_pct.items()},
            "better_at_bound": self.better_at_bound,
            "alike_below_significance": self.alike_below_significance(),
        }

    def alike_below_significance(self) -> list[str]:
        """The effects added beside the candidate that each improve its fit by more than the tie margin
        (:data:`.scoring.TIE_NATS`), within that margin of each other, while none counts: a lag or a delay may be
        there, and these data do not say which (empty otherwise)."""
        added = {k: v for k, v in self.scores.items() if " for " not in k}
        if self.selected is not None or len(added) < 2 or min(added.values()) <= TIE_NATS:
            return []
        return sorted(added) if max(added.values()) - min(added.values()) < TIE_NATS else []

    def line(self) -> str:
        """The result in words."""
        tried = ", ".join(f"{k} {v:.1f} nats" for k, v in self.scores.items())
        if self.selected is None:
            out = f"  beside it, no library effect of the signal path counts ({tried})"
            if self.better_at_bound:
                out += (
                    f"; {self.better_at_bound} fits far better but only with a base parameter at a bound of its "
                    "range (not counted: something else is still missing, or the candidate's form is off)"
                )
            alike = self.alike_below_significance()
            if alike:
                out += (
                    f"; {' and '.join(alike)} each improve the fit a little and alike: one of them may be there, "
                    f"not told apart: {SEPARATES_LAG_DELAY}"
                )
            return out
        vals = ", ".join(f"{k} = {v:.4g}" for k, v in self.values.items())
        how = f"selected in place of {self.replaces}" if self.replaces else "selected"
        out = (
            f"  beside it, the library's {self.selected} is {how} ({vals}; {tried}); residual with both "
            f"{self.after.ratio_to_noise:.3g} times the noise ({self.after.verdict.replace('_', ' ')})"
        )
        moved = moved_text(self.base_change_pct)
        if moved:
            out += f"; base parameters with both: {moved}"
        if self.tie_with:
            out += f"; a tie with {self.tie_with}: {SEPARATES_LAG_DELAY}"
        if self.better_at_bound:
            out += (
                f"; {self.better_at_bound} in its place fits better but only with a base parameter at a bound of "
                "its range (not counted: something else is still missing)"
            )
        return out


@dataclass
class _Trial:
    """One effect fitted beside the candidate, added or in place of another."""

    effect: type[Effect]
    replaces: str | None
    incumbent_doubted: bool = False  # the selection stated it could not tell the replaced effect from another
    score: float = 0.0
    counts: bool = False
    at_bound: bool = False
    result: FitResult | None = None
    objective: Objective | None = None

    @property
    def label(self) -> str:
        return self.effect.name if self.replaces is None else f"{self.effect.name} for {self.replaces}"


def beside_candidate(
    screening: Screening, diagnosis: Diagnosis, noise_scales: dict[str, float]
) -> BesideCandidate | None:
    """Fit the library's signal-path effects beside the diagnosis' fitted candidate (module docstring).

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis, with its candidate fitted (:func:`.candidate_fit.choose_candidate`).
    noise_scales : dict of str to float
        The channels' noise (the objective's scales before any weighting).

    Returns
    -------
    BesideCandidate or None
        None when there is no fitted candidate, it removes less than :data:`MIN_CANDIDATE_CUT` of the
        unexplained variance, it leaves the recording at the noise (nothing left to explain) without a lag of its
        own, or every signal-path effect is already in the model.
    """
    cand = diagnosis.candidate
    fit = cand.fit if cand is not None else None
    if fit is None or fit.state is None or fit.variance_cut < MIN_CANDIDATE_CUT:
        return None
    if fit.after.explained and not fit.with_library:  # nothing left to explain (a carried lag is still reported)
        return None
    state = fit.state
    own_model = set(diagnosis.model.split("+"))
    by_name = {e.name: e for e in screening.model.candidates if e.name in SIGNAL_PATH}
    by_selection = [n for n in diagnosis.selected if n in by_name and n not in own_model]
    carried = [n for n in fit.with_library if n in by_name]  # fitted with the candidate (found through it)
    taken = by_selection + carried
    doubted = {s.effect for s in diagnosis.ranking if s.effect in by_selection and s.note}
    trials = [
        _Trial(e, r, r in doubted)
        for e in by_name.values()
        if e.name not in own_model | set(taken)
        for r in (None, *taken)
    ]
    if not trials:
        return None
    reference = _reference(state, taken, by_name)
    for trial in trials:
        _fit_trial(trial, state, reference, by_name)
    scores = {t.label: t.score for t in trials}
    counting = sorted((t for t in trials if t.counts), key=lambda t: -t.score)
    if not counting:
        if carried:
            return _carried(fit, trials, scores, screening)
        at_bound = max(
            (t for t in trials if t.at_bound and t.score > SIGNIFICANCE), key=lambda t: t.score, default=None
        )
        return BesideCandidate(None, scores=scores, better_at_bound=at_bound.label if at_bound else None)
    best = counting[0]
    rival = next((t for t in counting[1:] if t.effect is not best.effect), None)
    tie = rival.effect.name if rival is not None and best.score - rival.score < TIE_NATS else None
    if rival is not None and tie is None:
        corner, fast = smooth_input_share(screening.exps, screening.model.comp, screening.model.nominal)
        if fast < SMOOTH_INPUT_SHARE:  # the selection's own rule (:mod:`.lag_delay`): nothing tells them apart
            tie = rival.effect.name
    comp, res = state.composition, best.result
    return BesideCandidate(
        best.effect.name,
        best.replaces,
        scores,
        {p.name: float(res.vector[comp.param_index(p.name)]) for p in best.effect.parameters},
        {fit.file_name(n): float(res.vector[comp.param_index(n)]) for n in state.fitted},
        unexplained(best.objective, np.asarray(res.vector), noise_scales),
        tie,
        change_pct(comp, res.vector, state.nominal, _base(state)),
    )


def _carried(fit, trials: list[_Trial], scores: dict[str, float], screening: Screening) -> BesideCandidate:
    """The signal-path effect the candidate was fitted with (found through it), reported as selected beside it
    when no trial beats it: with a tie stated when the other one in its place scores within
    :data:`.scoring.TIE_NATS` of it, or the input is too smooth to tell them apart (the selection's rule); when
    the other one scores clearly better but only with a base parameter at a bound, that is said instead."""
    state = fit.state
    name = next(n for n in fit.with_library if n in SIGNAL_PATH)
    swap = next((t for t in trials if t.replaces == name), None)
    tie = better = None
    if swap is not None:
        _, fast = smooth_input_share(screening.exps, screening.model.comp, screening.model.nominal)
        if swap.at_bound and swap.score >= TIE_NATS:
            better = swap.effect.name
        elif swap.score > -TIE_NATS or fast < SMOOTH_INPUT_SHARE:
            tie = swap.effect.name
    comp, vec = state.composition, state.result.vector
    effect = next(e for e in comp.effects if e.name == name)
    return BesideCandidate(
        name,
        None,
        scores,
        {p.name: float(vec[comp.param_index(p.name)]) for p in effect.parameters},
        {k: v for k, v in fit.values.items() if k not in {p.name for p in effect.parameters}},
        fit.after,
        tie,
        dict(fit.base_fitted),
        better,
    )


def _reference(state: CandidateFitState, taken: list[str], by_name: dict[str, type[Effect]]) -> FitResult:
    """What the trials are scored against: the candidate's own fit continued with the effort each trial gets (its
    parameters, those of the signal-path effects the selection took or the candidate carried, and the freed base
    parameters, from the same starts), kept when it fits better within the base parameters' ranges.

    The candidate's fit holds the selection's effects at the values found without the candidate, and stops
    where its own budget ends; a trial fits from there again.  Scored against a reference that was not, a
    delay fitted in place of a lag would win because it was fitted and the lag was not, and a delay fitted
    at 6 µs beside a carried lag scored 93 nats (a saturation after a 34 ms lag, on steps): the extra
    evaluations, not the delay."""
    ctx = state.context(_base(state), dict(by_name))
    own = [p.name for n in taken for p in by_name[n].parameters if p.name not in state.fitted]
    free = [*state.fitted, *own, *_base(state)]
    fits = [converged_fit(ctx, vec, free, MAX_NFEV) for vec in _starts(state, state.result)]
    within = [f for f in fits if not base_at_bounds(ctx, np.asarray(f.vector))]
    best = min(within, key=lambda f: f.rss_after, default=None)
    return state.result if best is None or best.rss_after >= state.result.rss_after else best


def _fit_trial(trial: _Trial, state: CandidateFitState, reference: FitResult, by_name: dict[str, type[Effect]]) -> None:
    """Fit one trial from each of :func:`_starts` and score the better against the reference fit."""
    ctx = state.context(_base(state), dict(by_name))
    obj = ctx.obj
    own = [p.name for p in trial.effect.parameters]
    off = {p.name for p in by_name[trial.replaces].parameters} if trial.replaces else set()
    free = [n for n in (*state.fitted, *own, *_base(state)) if n not in off]  # the replaced effect stays off
    fits = []
    for vec0 in _starts(state, reference):
        vec = vec0 if trial.replaces is None else ctx.neutralise(vec0, trial.replaces)
        start = best_effect_start(obj, state.composition, vec, trial.effect)
        fits.append(converged_fit(ctx, start, free, MAX_NFEV))
    within = [f for f in fits if not base_at_bounds(ctx, np.asarray(f.vector))]
    res = min(within or fits, key=lambda f: f.rss_after)
    r0, ids = reference.residual, obj.channel_ids
    k = len(own) - (len(by_name[trial.replaces].parameters) if trial.replaces else 0)
    if reference is state.result:  # base parameters the trial frees beyond the candidate's fit
        k += len(_base(state)) - len(state.base_names)
    trial.score, _ = score(r0, res, k, channels=ids, blocks=obj.block_ids)
    if not within and trial.score > SIGNIFICANCE:
        # far better but at a bound: the fit may only be passing there (a lag beside a dead zone, 60 s at 1 kHz:
        # Tcu at its bound after 20 evaluations, 333 nats; inside the ranges after 20 more, 697 nats)
        more = converged_fit(ctx, np.asarray(res.vector), free, MAX_NFEV)
        if more.rss_after < res.rss_after:
            res = more
            trial.score, _ = score(r0, res, k, channels=ids, blocks=obj.block_ids)
    if trial.replaces is None:
        trial.counts = significant(
            trial.score, reference.rss_after, res.rss_after, len(res.residual), r0, res.residual, ids
        )
    else:  # the incumbent was chosen by the selection's rules, unless it said it could not tell
        trial.counts = trial.score > (TIE_NATS if trial.incumbent_doubted else SIGNIFICANCE)
    if base_at_bounds(ctx, np.asarray(res.vector)):  # something still missing is absorbed there
        trial.counts, trial.at_bound = False, True
    trial.result, trial.objective = res, obj


def _starts(state: CandidateFitState, reference: FitResult) -> list[np.ndarray]:
    """Where a trial's fit starts: the reference fit, and the same with the candidate's parameters as discovery
    regressed them (without the effect tried, the candidate's own fit may have bent its terms to stand in for
    it: a dead zone after a 29 ms lag fitted as −1.57·sat(u, 0.24) for the −1·sat(u, 0.37) regressed and
    −1·sat(u, 0.36) hidden, from where the lag's fit ends with a base parameter at a bound)."""
    vec = np.asarray(reference.vector)
    if not state.regressed:
        return [vec]
    regressed = vec.copy()
    for name, value in state.regressed.items():
        regressed[state.composition.param_index(name)] = value
    return [vec] if np.array_equal(regressed, vec) else [vec, regressed]


def _base(state: CandidateFitState) -> tuple[str, ...]:
    """The base parameters the fits beside the candidate free: the candidate's, or every one it may free (a
    lag absorbed by the base parameters comes out only when they are fitted with it)."""
    return state.base_names or state.freeable
