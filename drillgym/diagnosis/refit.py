"""Refit a recording with effects of the library added (``drillgym identify --add-effect``).

The added effects' parameters are fitted jointly (each effect's own variables
and bounds, :mod:`.effects`); with no effect named, the configuration's base
parameters are refitted instead (upper: the upper stage; torsional, coupled:
the brake law; lateral: the lateral stage; free_vibration: Jl, bl, Tcl).
R² per channel before and after comes from the same comparison
(multiple shooting for brake configurations, see :mod:`.ranking`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import FitVariable, Objective, fit_parameters
from ..identification.segmented import SegmentedModel
from ..identification.staged import STAGES
from ..io import TimeSeries
from ..params import RigParams
from .compare import compare
from .effects import get_effect
from .ranking import BASE_STAGE, default_segment, default_weights

__all__ = ["RefitResult", "refit", "BASE_STAGE"]



@dataclass
class RefitResult:
    """Parameters after the refit and the error before/after."""

    params: RigParams
    r2_before: dict[str, float]
    r2_after: dict[str, float]
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    values: dict[str, float]
    std: dict[str, float]
    effects: list[str]
    warnings: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"r2_before": self.r2_before, "r2_after": self.r2_after, "rms_before": self.rms_before,
                "rms_after": self.rms_after, "effects": self.effects, "fitted": self.values, "std": self.std,
                "warnings": self.warnings, "params": self.params.to_dict()}


def refit(data: "TimeSeries | Experiment", params: RigParams | None = None, config=None, *,
          effects: Sequence[str] = (), segment_s: float | None = -1.0, compare_rate_hz: float = 50.0,
          max_nfev: int = 30) -> RefitResult:
    """Fit the named effects (or, with none, the configuration's base parameters) to one recording."""
    base = params or RigParams()
    ex = data if isinstance(data, Experiment) else prepare_experiment(data, config, compare_rate_hz=compare_rate_hz)
    if segment_s is not None and segment_s < 0:
        segment_s = default_segment(ex.config)
    effs = [get_effect(n) for n in effects]
    for e in effs:
        if not e.applies_to(ex.config):
            raise ValueError(f"effect {e.name!r} does not act in configuration '{ex.config.label}' "
                             f"(it applies to: {', '.join(c.label for c in e.configurations)})")
    if effs:
        variables: list[FitVariable] = []
        sizes = []
        for e in effs:
            v = e.variables(base)
            variables += v
            sizes.append(len(v))

        def apply(vec: np.ndarray, z: np.ndarray) -> np.ndarray:
            i = 0
            for e, n in zip(effs, sizes):
                vec = e.apply(vec, z[i:i + n])
                i += n
            return vec
    else:
        names = STAGES[BASE_STAGE[ex.config]].parameters
        variables = [FitVariable.relative(base, n, 0.5, 2.0) if getattr(base, n) != 0 else
                     FitVariable(n, 0.0, -0.5, 0.5, 0.01) for n in names]
        apply = None
    model = SegmentedModel([ex], segment_s)
    obj = Objective(model, default_weights(ex.config))
    model.refine_initial_speeds(base.to_vector(), obj.weights, obj.scales)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = fit_parameters(obj, base, variables, apply=apply, max_nfev=max_nfev)
    before = compare(ex, base, segment_s=segment_s)
    after = compare(ex, res.params, segment_s=segment_s)
    values = {}
    for e in effs:
        values.update({k: getattr(res.params, k) for k in e.parameters})
    if not effs:
        values = dict(res.values)
    return RefitResult(res.params, {c: m["r2"] for c, m in before.metrics.items()},
                       {c: m["r2"] for c, m in after.metrics.items()},
                       {c: m["rms"] for c, m in before.metrics.items()},
                       {c: m["rms"] for c, m in after.metrics.items()}, values, res.std,
                       [e.name for e in effs], res.warnings)
