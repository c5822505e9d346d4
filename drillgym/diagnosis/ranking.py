"""The report step: the selection's ranking, as a :class:`~.results.Diagnosis`.

:func:`report` turns what the search and the checks kept into the diagnosis: the selected effects first,
in the order accepted, then the rest by their last score; the base parameters that moved; the warnings.
The one-at-a-time ranking of each candidate alone is :mod:`.one_at_a_time`.
"""

from __future__ import annotations

import math

from ..effects import Composition, Effect
from ..params import N_PARAMS, RigParams
from .context import BASE_BOUNDS, BRAKE_BOUNDS
from .effective import effective_samples
from .effects import label_effects
from .lag_delay import held_timing_warning, smooth_input_warning
from .results import Diagnosis, EffectScore, Selection
from .state import Screening, SearchOutcome
from .timing import LAG_DELAY

__all__ = ["report"]


def report(screening: Screening, outcome: SearchOutcome) -> Diagnosis:
    """The diagnosis of what the search and the checks kept.

    Parameters
    ----------
    screening : Screening
        The recording screened.
    outcome : SearchOutcome
        The model kept, the search orders' paths, the lag/delay decision.

    Returns
    -------
    Diagnosis
        The diagnosis.
    """
    model, out = screening.model, outcome.kept
    comp, vec, vec0 = model.comp, out.vector, model.nominal
    skipped = dict(screening.skipped)
    skipped.update(out.excluded)
    by_name = {e.name: e for e in model.candidates}
    ranking = _selected_scores(out, comp, by_name) + _rest_scores(out, by_name)
    for name, why in out.dropped.items():
        if name not in {r.effect for r in ranking}:
            skipped[name] = why
    base = [n for n in model.base_names if comp.owner(n) is None]  # not a model effect's, refitted with them
    refitted = {n: float(vec[comp.param_index(n)]) for n in base} if out.base_off else {}
    ne0 = effective_samples(model.obj.residual_matrix(vec0[None, :])[0], model.obj.block_ids)
    warn = list(out.base_warnings)
    if out.at_bounds:
        warn.append(
            f"base parameters at the edge of their range (±{100 * (BASE_BOUNDS[1] - 1):.0f} %, the brake's "
            f"±{100 * (BRAKE_BOUNDS[1] - 1):.0f} %): "
            f"{', '.join(out.at_bounds)}: an effect the library lacks is absorbed by them, or the base "
            f"model is further off than a few percent (run identify-staged first)"
        )
    nominal_vector = vec.copy()
    nominal_vector[:N_PARAMS] = vec0[:N_PARAMS]
    return Diagnosis(
        ranking,
        screening.config,
        math.sqrt(out.rss_nominal / out.n),
        screening.channel_rms_before,
        ne0,
        screening.segment_s,
        skipped,
        refitted,
        screening.model_label,
        selected=list(out.selected),
        base_parameters=out.moved,
        base_off=out.base_off,
        base_score=out.base_score,
        warnings=warn
        + smooth_input_warning(screening.exps, comp, vec0, out.moved, out.selected)
        + held_timing_warning(screening.exps, comp, vec0, label_effects(screening.model_label))
        + _offset_or_force(out.selected, comp, vec),
        rmse_after=math.sqrt(out.rss_final / out.n),
        composition=comp,
        vector=vec,
        params=RigParams.from_vector(vec[:N_PARAMS]),
        nominal_vector=nominal_vector,
        paths=outcome.paths,
        lag_delay=outcome.lag_delay.to_json() if outcome.lag_delay is not None else None,
        sensor_misfit=outcome.sensor_misfit,
        at_bounds=list(out.at_bounds),
    )


def _offset_or_force(selected, comp: Composition, vec) -> list[str]:
    """An LVDT offset in the model (selected, or held there beside a candidate) stated as indistinguishable from a
    constant lateral force: the lateral motion is linear in the forces on the centre, so a constant force F shifts
    the disc by F / k, which the LVDTs read as an offset (seen on an independent rig's brake pad: its contact force
    was named ``lvdt_offset``)."""
    if "lvdt_offset" not in comp.names:
        return []
    x0, y0 = (float(vec[comp.param_index(n)]) for n in ("lvdt_x0", "lvdt_y0"))
    if "lvdt_offset" not in selected and x0 == 0.0 and y0 == 0.0:  # a candidate the selection left switched off
        return []
    k = float(vec[comp.param_index("k")])
    return [
        f"lvdt_offset ({1e3 * x0:+.3f}, {1e3 * y0:+.3f}) mm reads as a constant lateral force of "
        f"({k * x0:+.3g}, {k * y0:+.3g}) N on the disc's centre (a brake pad's contact, a preload) would: either "
        f"shifts the disc by F / k and this recording does not tell them apart; the LVDTs read with the disc held "
        f"at its centre and the brake released do"
    ]


def _selected_scores(out: Selection, comp: Composition, by_name: dict[str, type[Effect]]) -> list[EffectScore]:
    """The selected effects' scores, in the order accepted; an effect that took a lag's or a delay's place
    gets the step of the one it replaced."""
    N, vec, fit = out.n, out.vector, out.fit
    ranking: list[EffectScore] = []
    for st in out.steps:
        if st.effect not in out.selected:
            continue
        vals = {p.name: float(vec[comp.param_index(p.name)]) for p in by_name[st.effect].parameters}
        std = {
            k: (fit.std.get(k, st.std.get(k, float("nan"))) if fit is not None else st.std.get(k, float("nan")))
            for k in vals
        }
        ranking.append(
            EffectScore(
                st.effect,
                st.score,
                math.sqrt(st.rss_before / N),
                math.sqrt(st.rss_after / N),
                vals,
                std,
                {},
                " ".join(by_name[st.effect].signature.split()),
                True,
                out.ties.get(st.effect, ""),
            )
        )
    for name in out.selected:  # a lag/delay swap: the selected one took the other's place
        if name not in {r.effect for r in ranking}:
            vals = {p.name: float(vec[comp.param_index(p.name)]) for p in by_name[name].parameters}
            std = {k: fit.std.get(k, float("nan")) if fit is not None else float("nan") for k in vals}
            st = next(s for s in out.steps if s.effect in LAG_DELAY)
            ranking.append(
                EffectScore(
                    name,
                    st.score,
                    math.sqrt(st.rss_before / N),
                    math.sqrt(st.rss_after / N),
                    vals,
                    std,
                    {},
                    " ".join(by_name[name].signature.split()),
                    True,
                    out.ties.get(name, ""),
                )
            )
    return ranking


def _rest_scores(out: Selection, by_name: dict[str, type[Effect]]) -> list[EffectScore]:
    """The effects not selected, by their score in the last round."""
    N = out.n
    rest = sorted((s for n, s in out.last_round.items() if n not in out.selected), key=lambda s: -s.score)
    return [
        EffectScore(
            st.effect,
            st.score,
            math.sqrt(st.rss_before / N),
            math.sqrt(st.rss_after / N),
            st.values,
            st.std,
            {},
            " ".join(by_name[st.effect].signature.split()),
            False,
            out.dropped.get(st.effect, ""),
        )
        for st in rest
    ]
