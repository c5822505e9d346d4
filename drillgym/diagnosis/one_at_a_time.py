"""The one-at-a-time ranking: each candidate alone against the model (:func:`rank_effects`).

It is the first round of the selection, without the base parameters: every candidate is tried as the model +
candidate and fitted alone (its few parameters, everything else held) by multiple shooting, and scored

    score = N_eff ln(RSS_before / RSS_after) − k ln(N_eff)

with k the effect's number of parameters and N_eff = N (1 − ρ)/(1 + ρ) from the lag-1 autocorrelation ρ
of the base residual.  An effect is *significant* when its score exceeds :data:`SIGNIFICANCE`, it removes
at least :data:`MIN_REDUCTION` of the residual RMS, and the variance it explains exceeds the noise
(:func:`.scoring.noise_floor`).  Significant effects whose scores tie (:data:`TIE_NATS`) are flagged as
indistinguishable (e.g. a small motor lag and a small input delay).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..effects import Composition, Effect
from ..errors import EffectError, FitFailedError
from ..identification.experiment import Experiment
from ..identification.fitting import FitResult, FitVariable, Objective, base_vector, fit_parameters
from ..identification.segmented import SegmentedModel
from ..io import TimeSeries
from ..params import RigParams
from .effective import effective_samples
from .effects import applies_to, fit_variables, with_candidate
from .results import Diagnosis, EffectScore
from .scoring import noise_floor
from .screening import (
    condition,
    default_segment,
    default_weights,
    excitation_missing,
    prepare_experiments,
)
from .segments import place_segment_starts
from .state import DiagnosisOptions, transfer

__all__ = ["rank_effects", "SIGNIFICANCE", "MIN_REDUCTION", "TIE_NATS"]

SIGNIFICANCE = 15.0  # score (nats) above which an effect counts as found, one at a time
MIN_REDUCTION = 0.25  # fraction of the residual RMS an effect must remove to count, one at a time
TIE_NATS = 2.0  # significant effects whose scores differ by less (or by < 2 %) are reported as indistinguishable


def _fit_effect(obj: Objective, start: np.ndarray, variables: Sequence[FitVariable], max_nfev: int) -> FitResult:
    """Fit one effect's variables (the rest of the vector held); the result carries its per-channel RMS."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit_parameters(obj, start, variables, max_nfev=max_nfev)
    res.channel_rms = obj.channel_rms(res.vector)
    return res


def rank_effects(
    data: TimeSeries | Experiment | Sequence[Experiment],
    params: RigParams | None = None,
    config: Any = None,
    *,
    options: DiagnosisOptions | None = None,
    max_nfev: int = 12,
    n_second_pass: int = 3,
    **settings: Any,
) -> Diagnosis:
    """Rank candidate effects one at a time against the model (see the module docstring).

    The speeds at the segment starts (estimated from the data by differentiation) are first refined for
    the model, so that their noise is not taken for a missing effect; the ``n_second_pass`` best effects are
    then refitted with the speeds refined for the extended model (each model gets its own nuisance states).

    Parameters
    ----------
    data : TimeSeries, Experiment or sequence of Experiment
        A recording or prepared experiments.
    params : RigParams, optional
        Base parameters (default: the identified set of docs/model.md).
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    options : DiagnosisOptions, optional
        The settings (candidates, model effects, segments, comparison grid, speed refinement); the
        selection's own settings (``fixed_base``, ``n_joint``, ``max_effects``, ``discover``) are not used.
    max_nfev : int, optional
        Least-squares evaluations per effect.  Default 12.
    n_second_pass : int, optional
        Leading effects refitted with the speeds refined for them.  Default 3.
    **settings
        Fields of :class:`DiagnosisOptions`, overriding ``options``.

    Returns
    -------
    Diagnosis
        The ranking (nothing selected).
    """
    from dataclasses import replace

    from ..effects import compose
    from .effects import effects_for, get_effect

    opts = replace(options or DiagnosisOptions(), **settings)
    base = params or RigParams()
    comp0, values0 = compose(opts.base_effects, opts.effect_params)
    exps, scales = condition(prepare_experiments(data, config, opts.compare_rate_hz, opts.lvdt_lowpass_hz))
    cfg = exps[0].config
    candidates = [get_effect(e) for e in opts.effects] if opts.effects else effects_for(cfg)
    segment_s = default_segment(cfg) if opts.segment_s is not None and opts.segment_s < 0 else opts.segment_s
    model = SegmentedModel(exps, segment_s, composition=comp0)
    if segment_s is not None:  # the effects are compared on well-started segments (.segments)
        place_segment_starts(model)
    obj = Objective(model, default_weights(cfg), scales)
    vec0 = base_vector(comp0, base, values0)
    if opts.refine_speeds:
        model.refine_initial_speeds(vec0, obj.weights, obj.scales)
    r0 = obj.residual_matrix(vec0[None, :])[0]
    ch0 = obj.channel_rms(vec0)
    skipped: dict[str, str] = {}
    tried = _one_at_a_time(obj, vec0, comp0, candidates, exps, skipped, max_nfev, base)
    if opts.refine_speeds:
        _second_pass(tried, n_second_pass, max_nfev)
    n_eff = effective_samples(r0, obj.block_ids)
    return Diagnosis(
        _scored(tried, r0, n_eff),
        cfg,
        math.sqrt(float(r0 @ r0) / len(r0)),
        ch0,
        n_eff,
        segment_s,
        skipped,
        {},
        comp0.label,
    )


def _one_at_a_time(
    obj: Objective,
    vec0: np.ndarray,
    comp0: Composition,
    candidates: Sequence[type[Effect]],
    exps: Sequence[Experiment],
    skipped: dict[str, str],
    max_nfev: int,
    base: RigParams,
) -> dict:
    """Each candidate fitted alone in the model + candidate: {name: (effect, objective, start, fit)}; the
    candidates not tried and those whose fits failed are recorded in ``skipped`` with why (the recordings'
    excitation judged with the base parameters ``base``)."""
    cfg = exps[0].config
    tried: dict = {}
    for eff in candidates:
        name = eff.name
        if name in comp0.names:
            skipped[name] = "already in the model"
            continue
        if not applies_to(eff, cfg):
            skipped[name] = f"does not act in configuration '{cfg.label}'"
            continue
        why = excitation_missing(eff, exps, base)
        if why:
            skipped[name] = why
            continue
        try:
            comp = with_candidate(comp0, eff)
            obj_c = Objective(obj.model.with_composition(comp), obj.weights, obj.scales)
            start = transfer(vec0, comp0, comp)
            tried[name] = (eff, obj_c, start, _fit_effect(obj_c, start, fit_variables(comp, eff), max_nfev))
        except (FitFailedError, EffectError) as exc:  # a fit that names why it failed, or an effect that cannot run
            skipped[name] = f"fit failed: {exc}"
    return tried


def _second_pass(tried: dict, n_second_pass: int, max_nfev: int) -> None:
    """The leaders refitted with the segments' start speeds refined for the extended model (in place)."""
    for name in sorted(tried, key=lambda n: tried[n][3].rss_after)[:n_second_pass]:
        eff, obj_c, start, res = tried[name]
        obj_c.model.refine_initial_speeds(res.vector, obj_c.weights, obj_c.scales)
        warm = fit_variables(obj_c.model.composition, eff, values=res.values)
        try:
            res2 = _fit_effect(obj_c, start, warm, max(4, max_nfev // 2))
        except FitFailedError:
            continue
        if res2.rss_after < res.rss_after:
            tried[name] = (eff, obj_c, start, res2)


def _scored(tried: dict, r0: np.ndarray, n_eff: float) -> list[EffectScore]:
    """The candidates' scores against the model's residual ``r0``, best first, near-ties noted."""
    rss0, N = float(r0 @ r0), len(r0)
    rmse0 = math.sqrt(rss0 / N)
    scores: list[EffectScore] = []
    for name, (eff, _, _, res) in tried.items():
        rss1 = max(res.rss_after, 1e-300)
        k = len(res.names)
        score = n_eff * math.log(rss0 / rss1) - k * math.log(n_eff) if rss0 > 0 else 0.0
        rmse1 = math.sqrt(rss1 / N)
        sig = (
            score > SIGNIFICANCE and rmse1 < (1 - MIN_REDUCTION) * rmse0 and rmse0**2 - rmse1**2 > noise_floor(rmse1**2)
        )
        scores.append(
            EffectScore(
                name,
                score,
                rmse0,
                rmse1,
                dict(res.values),
                dict(res.std),
                res.channel_rms or {},
                " ".join(eff.signature.split()),
                sig,
            )
        )
    scores.sort(key=lambda s: -s.score)
    for a, b in zip(scores, scores[1:]):  # near-ties: the data cannot tell these effects apart
        if a.significant and b.significant and a.score - b.score < max(TIE_NATS, 0.02 * abs(a.score)):
            a.note = (
                f"indistinguishable from {b.effect} on these data (scores {a.score:.1f} vs {b.score:.1f}); "
                "an input with sharper steps or a higher sample rate would separate them"
            )
    return scores
