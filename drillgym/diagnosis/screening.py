"""The screen step: the recording prepared, conditioned, and the candidates it can show.

A recording (or prepared experiments) is compared on a grid of ``compare_rate_hz``, each channel in noise
units read robustly from the data (:func:`.segments.robust_noise`: the encoder count, not interpolation
round-off), in multiple-shooting segments that start where the data's state is well known
(:func:`.segments.place_segment_starts`).  Every candidate that acts in the configuration and that the
recording can excite (its ``needs``: negative rotation, a lower-disc angle) is usable; the others are
skipped with the reason.  The usable candidates, and those the data cannot show but that vanish at their
neutral values, form one search composition (:func:`.context.search_composition`): one compiled model per
configuration and candidate list, whatever the recording excites, so the kernels compiled for one
recording (or by ``make venv``) serve the next.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..configurations import Configuration
from ..effects import Composition, Effect, compose
from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import Objective, base_vector
from ..identification.segment_length import default_segment, segment_length
from ..io import TimeSeries
from ..params import RigParams
from .effects import applies_to, effects_for, get_effect
from .search_model import (
    SearchModel,
    base_free_parameters,
    default_weights,
    neutral_values,
    search_composition,
    selection_model,
)
from .segments import robust_noise
from .state import REFIT_BUDGET, DiagnosisOptions, Screening

__all__ = [
    "DiagnosisOptions",
    "Screening",
    "REFIT_BUDGET",
    "screen",
    "prepare_experiments",
    "condition",
    "excitation_missing",
    "default_weights",
    "default_segment",
]


def prepare_experiments(
    data: TimeSeries | Experiment | Sequence[Experiment],
    config: str | Configuration | None,
    compare_rate_hz: float,
    lvdt_lowpass_hz: float | None,
) -> list[Experiment]:
    """The experiments of a recording, an experiment, or several.

    Parameters
    ----------
    data : TimeSeries, Experiment or sequence of Experiment
        What to diagnose.
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    compare_rate_hz : float
        Comparison grid rate (Hz) of a recording.
    lvdt_lowpass_hz : float or None
        LVDT low-pass cut-off (Hz) of a recording.

    Returns
    -------
    list of Experiment
        The experiments.
    """
    if isinstance(data, TimeSeries):
        return [prepare_experiment(data, config, compare_rate_hz=compare_rate_hz, lvdt_lowpass_hz=lvdt_lowpass_hz)]
    if isinstance(data, Experiment):
        return [data]
    return list(data)


def condition(exps: Sequence[Experiment]) -> tuple[list[Experiment], dict[str, float]]:
    """The experiments with their noise read robustly (:func:`.segments.robust_noise`).

    Parameters
    ----------
    exps : sequence of Experiment
        The experiments.

    Returns
    -------
    tuple of (list of Experiment, dict of str to float)
        The conditioned experiments, and each channel's noise scale (the smallest of the experiments').
    """
    conditioned = [robust_noise(ex) for ex in exps]
    return [c[0] for c in conditioned], {c: min(s[c] for _, s in conditioned) for c in conditioned[0][1]}


#: a lower disc at rest (rad/s) ...
REST_SPEED = 0.1
#: ... holding a backward pull of the string beyond this share of the brake's static level shows a backward level
#: above the forward one (the stick set's lower edge held it); a lower backward level shows as a backward slip
HELD_BACK_SHARE = 1.0
#: the share of samples turning backwards or held back that shows a direction-dependent brake
NEGATIVE_SHARE = 0.02


def excitation_missing(effect: type[Effect], exps: Sequence[Experiment], params: RigParams | None = None) -> str:
    """Why the recordings cannot show an effect (its ``needs``), or ''.

    ``negative_rotation`` (a brake whose levels depend on the direction) is shown by samples where the lower disc
    turns backwards, and by samples where it rests while the string pulls it backwards beyond
    :data:`HELD_BACK_SHARE` of the static level (``kθ (θu − θl) ≤ −Ts``, the identified set's or the given one):
    there only a backward static level above the forward one holds it.

    Parameters
    ----------
    effect : Effect class
        The effect.
    exps : sequence of Experiment
        The recordings.
    params : RigParams, optional
        The base parameters the pull is measured with (default: the identified set).

    Returns
    -------
    str
        The reason, or ''.
    """
    if "negative_rotation" in effect.needs:
        p = params or RigParams()
        shown = sum(_backwards(ex, p) for ex in exps if "omega_l" in ex.rates)
        if shown < NEGATIVE_SHARE * sum(ex.n for ex in exps):
            return (
                "the lower disc hardly turns backwards, nor rests against a backward pull beyond its static friction, "
                "in these data (needs negative rotation)"
            )
    if "theta_l" in effect.needs and not any("theta_l" in ex.meas for ex in exps):
        return "the recording has no lower disc angle (needs theta_l)"
    return ""


def _backwards(ex: Experiment, p: RigParams) -> int:
    """Samples where the lower disc turns backwards, or rests held against a backward pull (:data:`HELD_BACK_SHARE`
    of Ts)."""
    wl = ex.rates["omega_l"]
    back = wl < -REST_SPEED
    if "theta_u" in ex.meas and "theta_l" in ex.meas:
        pull = p.ktheta * (ex.meas["theta_u"] - ex.meas["theta_l"])
        back |= (np.abs(wl) <= REST_SPEED) & (pull <= -HELD_BACK_SHARE * p.Ts)
    return int(np.sum(back))


def screen(
    data: TimeSeries | Experiment | Sequence[Experiment],
    params: RigParams | None,
    config: str | Configuration | None,
    options: DiagnosisOptions,
) -> Screening:
    """Prepare and condition the recordings, sort the candidates, build the search model.

    Parameters
    ----------
    data : TimeSeries, Experiment or sequence of Experiment
        What to diagnose.
    params : RigParams or None
        Nominal base parameters (default: the identified set of docs/model.md).
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    options : DiagnosisOptions
        The settings.

    Returns
    -------
    Screening
        The recordings, the search model and the candidates skipped.
    """
    base = params or RigParams()
    comp0, values0 = compose(options.base_effects, options.effect_params)
    exps = prepare_experiments(data, config, options.compare_rate_hz, options.lvdt_lowpass_hz)
    cfg = exps[0].config
    comp0.refuse_not_acting(cfg.label, "base_effects")
    if options.effects is not None:
        Composition(tuple(get_effect(e) for e in options.effects)).refuse_not_acting(cfg.label, "effects")
    candidates = [get_effect(e) for e in options.effects] if options.effects else effects_for(cfg)
    segment_s = segment_length(options.segment_s, exps)
    exps, scales = condition(exps)
    usable, held, skipped = _sort_candidates(candidates, comp0, cfg, exps, base)
    # the candidates the data cannot show stay in the model at their neutral values (the kernels skip them)
    in_model = [e for e in candidates if e in usable or e in held]  # the candidates' order: one composition
    comp = search_composition(comp0, list(dict.fromkeys(in_model)))
    vec0 = base_vector(comp, base, {**values0, **neutral_values(in_model)})
    obj = Objective(selection_model(exps, segment_s, comp), default_weights(cfg), scales)
    brake_on = all(float(ex.meta.get("brake_normal_force_n", 1.0) or 0.0) != 0.0 for ex in exps)
    base_names = () if options.fixed_base else base_free_parameters(cfg, brake_on)
    if options.refit_model_effects:  # freed with the base parameters, as a part of the model diagnosed
        held = set(options.held_effect_params)
        base_names = (*base_names, *(n for n in comp0.effect_param_names if n not in held))
    model = SearchModel(obj, comp, vec0, usable, tuple(base_names))
    return Screening(exps, cfg, comp0.label, segment_s, model, skipped, obj.channel_rms(vec0))


def _sort_candidates(
    candidates: Sequence[type[Effect]],
    comp0: Composition,
    cfg: Configuration,
    exps: Sequence[Experiment],
    params: RigParams,
) -> tuple[list, list, dict[str, str]]:
    """(usable, held at their neutral values, skipped with why) of the candidates."""
    skipped: dict[str, str] = {}
    usable: list[type[Effect]] = []
    held: list[type[Effect]] = []
    for eff in candidates:
        if eff.name in comp0.names:
            skipped[eff.name] = "already in the model"
        elif not applies_to(eff, cfg):
            skipped[eff.name] = f"does not act in configuration '{cfg.label}'"
        elif eff.name in {u.name for u in usable + held}:
            continue
        elif excitation_missing(eff, exps, params):
            skipped[eff.name] = excitation_missing(eff, exps, params)
            if eff.neutral_values() is not None:
                held.append(eff)
        else:
            usable.append(eff)
    return usable, held, skipped
