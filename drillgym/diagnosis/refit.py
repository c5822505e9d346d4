"""Refit a recording with effects added (``drillgym identify --add-effect``).

The model before is the base parameters with the effects it already has (``base_effects``,
e.g. from a parameter file written by an earlier ``identify``); the model after adds the
named effects (the library's, an installed package's or a user's file) and fits their
parameters jointly (each parameter's own bounds, guess and scale: its effect's
:class:`~drillgym.effects.Parameter`), optionally with the configuration's base parameters
(``refit_base``) or any other parameters named in ``fit``.  With no effect added and nothing
named, the configuration's base parameters are refitted (upper: the upper stage;
torsional, coupled: the brake law; lateral: the lateral stage; free_vibration: Jl, bl, Tcl).
R² per channel before and after come from the same comparison (multiple shooting for brake
configurations, see :mod:`.ranking`).  The data's speeds at the segment starts are refined
for the starting model, the fit run, then refined again for the fitted model and the fit
repeated from its result (a poor starting guess must not bias the nuisance speeds).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ..configurations import Configuration
from ..effects import Composition, compose
from ..errors import InputError, InputTypeError
from ..identification.acting import check_fit_names
from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import FitVariable, Objective, base_vector, fit_parameters
from ..identification.segment_length import segment_length
from ..identification.segmented import SegmentedModel
from ..identification.staged import STAGES
from ..io import TimeSeries
from ..params import RigParams
from .compare import compare
from .effects import get_effect
from .option_checks import as_sequence, check_refit_options
from .search_model import default_weights

__all__ = ["RefitOptions", "RefitResult", "refit", "BASE_STAGE", "effect_records"]

#: the staged identification's stage whose parameters are a configuration's base parameters
BASE_STAGE = {
    Configuration.UPPER: "upper",
    Configuration.TORSIONAL: "brake",
    Configuration.COUPLED: "brake",
    Configuration.LATERAL: "lateral",
    Configuration.FREE_VIBRATION: "free_vibration",
}


def effect_records(
    comp: Composition,
    values: Mapping[str, float],
    specs: Mapping[str, str] | None = None,
    std: Mapping[str, float] | None = None,
) -> list[dict]:
    """The effects of a composition as reusable records.

    Parameters
    ----------
    comp : Composition
        The composition.
    values : mapping of str to float
        Its effects' parameter values.
    specs : mapping of str to str, optional
        Effect name -> the spec it was given by.
    std : mapping of str to float, optional
        Standard errors by parameter name: each record gets ``"std"`` with the finite ones of its parameters
        (they travel with the model file: the controllers' margins read them).

    Returns
    -------
    list of dict
        ``{"name", "spec", "file", "values", "kind"}`` per effect (``spec`` is what ``--add-effect`` accepts:
        the name, or ``file.py:NAME`` for a file's effect), with ``signal_path_position`` for a Delay or
        Input effect (1 = nearest the command: :meth:`drillgym.effects.Composition.signal_path`).
    """
    out = []
    for e in comp.effects:
        f = getattr(e, "__drillgym_file__", None)
        spec = (specs or {}).get(e.name) or (f"{f}:{e.name}" if f else e.name)
        out.append(
            {
                "name": e.name,
                "spec": spec,
                "file": f,
                "values": {p.name: float(values[p.name]) for p in e.parameters},
                **comp.order_fields(e.name),
            }
        )
        if std is not None:
            out[-1]["std"] = {
                p.name: float(std[p.name]) for p in e.parameters if math.isfinite(std.get(p.name, math.nan))
            }
    return out


@dataclass
class RefitResult:
    """The fitted model and the error before and after.

    Attributes
    ----------
    params : RigParams
        The base parameters after the fit.
    r2_before, r2_after : dict of str to float
        R² per channel before and after.
    rms_before, rms_after : dict of str to float
        RMS error per channel before and after (physical units).
    values, std : dict of str to float
        The fitted parameters and their standard errors, by name.
    effects : list of str
        The names of the effects added.
    warnings : list of str
        Identifiability warnings.
    composition : Composition or None
        The model's effects.
    effect_values : dict of str to float
        All their parameters.
    model_before : str
        The label of the model before.
    noise : dict of str to float
        The recording's noise level per channel (physical units), as the comparison estimates it.
    """

    params: RigParams
    r2_before: dict[str, float]
    r2_after: dict[str, float]
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    values: dict[str, float]
    std: dict[str, float]
    effects: list[str]
    warnings: list[str] = field(default_factory=list)
    composition: Composition | None = None
    effect_values: dict[str, float] = field(default_factory=dict)
    model_before: str = "base"
    noise: dict[str, float] = field(default_factory=dict)

    def effect_records(self) -> list[dict]:
        return effect_records(self.composition, self.effect_values) if self.composition is not None else []

    def to_json(self) -> dict:
        return {
            "r2_before": self.r2_before,
            "r2_after": self.r2_after,
            "rms_before": self.rms_before,
            "rms_after": self.rms_after,
            "effects_added": self.effects,
            "model_before": self.model_before,
            "effects": self.effect_records(),
            "fitted": self.values,
            "std": self.std,
            "warnings": self.warnings,
            "params": self.params.to_dict(),
        }


@dataclass
class RefitOptions:
    """What :func:`refit` adds and fits.

    Attributes
    ----------
    effects : sequence
        Effects to add and fit: names, ``path/to/file.py:NAME`` or Effect classes.
    effect_params : mapping of str to float, optional
        Starting values of the added effects' parameters (default: their guesses).
    base_effects : any, optional
        Effects already in the model.
    base_values : mapping of str to float, optional
        Their (held) values.
    fit : sequence of str
        Further parameters of the model to fit (base or effect names).
    refit_base : bool
        Also fit the configuration's base parameters (the stage of :data:`BASE_STAGE`).  Default False.
    segment_s : float or None
        Multiple-shooting segment length (s); -1: the configuration's default; None: one free run.
    compare_rate_hz : float
        Comparison grid rate (Hz) when a recording is given.  Default 50.
    max_nfev : int
        Least-squares evaluations.  Default 30.
    """

    effects: Sequence[Any] = ()
    effect_params: Mapping[str, float] | None = None
    base_effects: Any = None
    base_values: Mapping[str, float] | None = None
    fit: Sequence[str] = ()
    refit_base: bool = False
    segment_s: float | None = -1.0
    compare_rate_hz: float = 50.0
    max_nfev: int = 30

    def __post_init__(self) -> None:
        self.effects = as_sequence("effects", self.effects) or ()
        self.fit = as_sequence("fit", self.fit) or ()
        check_refit_options(self)


def refit(
    data: TimeSeries | Experiment,
    params: RigParams | None = None,
    config: Any = None,
    *,
    options: RefitOptions | None = None,
    **settings: Any,
) -> RefitResult:
    """Add effects to a model and fit them.

    Parameters
    ----------
    data : TimeSeries or Experiment
        The recording or a prepared experiment.
    params : RigParams, optional
        The model's base parameters (default: the identified set of docs/model.md).
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    options : RefitOptions, optional
        What to add and fit (default: :class:`RefitOptions` ()).
    **settings
        Fields of :class:`RefitOptions` (``effects``, ``effect_params``, ``base_effects``, ``base_values``,
        ``fit``, ``refit_base``, ``segment_s``, ``compare_rate_hz``, ``max_nfev``), overriding ``options``.

    Returns
    -------
    RefitResult
        The fitted model and the error before and after.

    Raises
    ------
    InputError
        An added effect or a base parameter to fit that does not act in the recording's configuration, or an
        added effect that ``base_effects`` holds already.
    FitError
        The model before or after the fit gives non-finite states on the recording (no R² or RMS).
    """
    if params is not None and not isinstance(params, RigParams):
        raise InputTypeError(f"params must be RigParams (None: the identified set), got {type(params).__name__}")
    o = replace(options or RefitOptions(), **settings)
    base = params or RigParams()
    ex = data if isinstance(data, Experiment) else prepare_experiment(data, config, compare_rate_hz=o.compare_rate_hz)
    segment_s = segment_length(o.segment_s, ex)
    check_fit_names(o.fit, ex.config)
    comp0, values0 = compose(o.base_effects, o.base_values)
    added = [get_effect(e) for e in o.effects]
    Composition(tuple(added)).refuse_not_acting(ex.config.label, "effects")
    again = [e.name for e in added if e.name in comp0.names]
    if again:
        raise InputError(
            f"refit: effect {again[0]!r} is in base_effects already; fit its parameters with fit=[...] instead"
        )
    comp = Composition(tuple(comp0.effects) + tuple(added))
    start_values = {**values0, **{k: v for k, v in (o.effect_params or {}).items()}}
    vec_start = base_vector(comp, base, comp.check_values(start_values))
    names: list[str] = [p.name for e in added for p in e.parameters]
    if o.refit_base or (not added and not o.fit):
        names += [n for n in STAGES[BASE_STAGE[ex.config]].parameters if n not in names]
    names += [n for n in o.fit if n not in names]
    for n in names:
        comp.param_index(n)  # a one-line error for an unknown name
    variables = [FitVariable.named(comp, n, vec_start) for n in names]
    model = SegmentedModel([ex], segment_s, composition=comp)
    obj = Objective(model, default_weights(ex.config))
    vec_before = base_vector(comp0, base, values0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # the data's speeds at the segment starts refined for the start, then fitted with the parameters
        model.refine_initial_speeds(vec_start, obj.weights, obj.scales, fresh=True)
        res = fit_parameters(obj, vec_start, variables, max_nfev=o.max_nfev, fit_speeds=True)
    before = compare(ex, vec_before, segment_s=segment_s, effects=comp0)
    after = compare(ex, res.vector, segment_s=segment_s, effects=comp)
    return RefitResult(
        res.params,
        {c: m["r2"] for c, m in before.metrics.items()},
        {c: m["r2"] for c, m in after.metrics.items()},
        {c: m["rms"] for c, m in before.metrics.items()},
        {c: m["rms"] for c, m in after.metrics.items()},
        dict(res.values),
        dict(res.std),
        [e.name for e in added],
        res.warnings,
        comp,
        res.effect_values,
        comp0.label,
        dict(after.noise),
    )
