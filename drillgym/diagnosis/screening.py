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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..configurations import Configuration
from ..effects import Composition, Effect, compose
from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import Objective, base_vector
from ..identification.segment_length import default_segment, segment_length
from ..io import TimeSeries
from ..params import RigParams
from .context import SelectionOptions
from .effects import applies_to, effects_for, get_effect
from .option_checks import as_sequence, check_diagnosis_options
from .search_model import SearchModel, base_free_parameters, neutral_values, search_composition, selection_model
from .segments import robust_noise

#: joint refits' budget, times the selection's, when the model's own effects are refitted with the base: a
#: discovered candidate fitted without the library effect beside it starts far from where the two end together
#: (a dead zone's width and a 39 ms motor lag: 21 ms after the usual 15 evaluations, 37 ms converged, and the
#: residual on the motor angle 30 -> 1.6 noise units)
REFIT_BUDGET = 3

__all__ = [
    "DiagnosisOptions",
    "Screening",
    "screen",
    "prepare_experiments",
    "condition",
    "excitation_missing",
    "default_weights",
    "default_segment",
]


@dataclass
class DiagnosisOptions:
    """The settings of a diagnosis.

    Attributes
    ----------
    effects : sequence, optional
        The candidates: names, ``path/to/file.py:NAME`` specs or Effect classes (default: the library's
        effects that act in the configuration).  A candidate must vanish at its neutral values
        (:func:`.context.neutral_values`).
    base_effects : any, optional
        Effects already in the model (as :func:`drillgym.effects.compose`), held at ``effect_params``.
    effect_params : mapping of str to float, optional
        Their values.
    segment_s : float or None
        Multiple-shooting segment length (s); -1: :func:`default_segment`; None: one free run.  Default -1.
    compare_rate_hz : float
        Comparison grid rate (Hz) when a recording is given.  Default 50.
    lvdt_lowpass_hz : float or None
        LVDT low-pass cut-off (Hz) when a recording is given.  Default 5.
    refine_speeds : bool
        Fit the segments' initial speeds with every model.  Default True.
    fixed_base : bool
        Hold the base parameters at the nominal ones (no re-identification).  Default False.
    refit_model_effects : bool
        Free the parameters of the model's own effects (``base_effects``) wherever the base parameters are
        freed (with ``fixed_base``: in their place): an estimate held fixed (a discovered candidate's first fit)
        leaves a residual no library effect beside it can remove, where refitting both together does.
        Default False.
    n_joint : int
        Candidates refitted jointly with the base parameters per round.  Default 2.
    max_effects : int
        At most this many effects are selected.  Default 4.
    discover : bool
        Also look for an effect outside the library in the residual torques (:mod:`.discovery`), on the
        recording's own samples (up to 250 Hz).  Default False.
    candidate_out : str or path, optional
        With ``discover``: where to write the candidate's effect file.
    """

    effects: Sequence[Any] | None = None
    base_effects: Any = None
    effect_params: Mapping[str, float] | None = None
    segment_s: float | None = -1.0
    compare_rate_hz: float = 50.0
    lvdt_lowpass_hz: float | None = 5.0
    refine_speeds: bool = True
    fixed_base: bool = False
    refit_model_effects: bool = False
    n_joint: int = 2
    max_effects: int = 4
    discover: bool = False
    candidate_out: Any = None

    def __post_init__(self) -> None:
        self.effects = as_sequence("effects", self.effects)
        check_diagnosis_options(self)

    def selection(self) -> SelectionOptions:
        """The options of the forward selection."""
        joint = SelectionOptions.max_nfev_joint * (REFIT_BUDGET if self.refit_model_effects else 1)
        return SelectionOptions(
            n_joint=self.n_joint, max_effects=self.max_effects, refine=self.refine_speeds, max_nfev_joint=joint
        )


@dataclass
class Screening:
    """A recording screened for the selection.

    Attributes
    ----------
    exps : list of Experiment
        The conditioned experiments.
    config : Configuration
        Their configuration.
    model_label : str
        The label of the model diagnosed (its effects).
    segment_s : float or None
        Multiple-shooting segment length (s).
    model : SearchModel
        The search model.
    skipped : dict of str to str
        Candidates not tried, and why.
    channel_rms_before : dict of str to float
        The nominal model's residual RMS per channel (noise units).
    """

    exps: list[Experiment]
    config: Configuration
    model_label: str
    segment_s: float | None
    model: SearchModel
    skipped: dict[str, str] = field(default_factory=dict)
    channel_rms_before: dict[str, float] = field(default_factory=dict)


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


def excitation_missing(effect: type[Effect], exps: Sequence[Experiment]) -> str:
    """Why the recordings cannot show an effect (its ``needs``), or ''.

    Parameters
    ----------
    effect : Effect class
        The effect.
    exps : sequence of Experiment
        The recordings.

    Returns
    -------
    str
        The reason, or ''.
    """
    if "negative_rotation" in effect.needs:
        neg = sum(np.sum(ex.rates["omega_l"] < -0.1) for ex in exps if "omega_l" in ex.rates)
        tot = sum(ex.n for ex in exps)
        if neg < 0.02 * tot:
            return "the lower disc hardly turns backwards in these data (needs negative rotation)"
    if "theta_l" in effect.needs and not any("theta_l" in ex.meas for ex in exps):
        return "the recording has no lower disc angle (needs theta_l)"
    return ""


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
    usable, held, skipped = _sort_candidates(candidates, comp0, cfg, exps)
    # the candidates the data cannot show stay in the model at their neutral values (the kernels skip them)
    in_model = [e for e in candidates if e in usable or e in held]  # the candidates' order: one composition
    comp = search_composition(comp0, list(dict.fromkeys(in_model)))
    vec0 = base_vector(comp, base, {**values0, **neutral_values(in_model)})
    obj = Objective(selection_model(exps, segment_s, comp), default_weights(cfg), scales)
    brake_on = all(float(ex.meta.get("brake_normal_force_n", 1.0) or 0.0) != 0.0 for ex in exps)
    base_names = () if options.fixed_base else base_free_parameters(cfg, brake_on)
    if options.refit_model_effects:  # freed with the base parameters, as a part of the model diagnosed
        base_names = (*base_names, *comp0.effect_param_names)
    model = SearchModel(obj, comp, vec0, usable, tuple(base_names))
    return Screening(exps, cfg, comp0.label, segment_s, model, skipped, obj.channel_rms(vec0))


def _sort_candidates(
    candidates: Sequence[type[Effect]], comp0: Composition, cfg: Configuration, exps: Sequence[Experiment]
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
        elif excitation_missing(eff, exps):
            skipped[eff.name] = excitation_missing(eff, exps)
            if eff.neutral_values() is not None:
                held.append(eff)
        else:
            usable.append(eff)
    return usable, held, skipped
