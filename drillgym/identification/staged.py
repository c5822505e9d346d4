"""The report's staged identification procedure (docs/model.md).

1. ``upper``: the upper part alone (string disconnected, Ju known) on θu:
   km, Tcu, ΔTcu, bu, Δbu.
2. lower part without brake:
   a. ``free_vibration``: upper disc clamped, lower disc released from a winding
      α0; Jl, bl, Tcl with kθ held at the string-geometry value (0.0813 N m/rad);
   b. the whole torsional system without brake (upper driven, lateral motion
      held): Jl, kθ, Tcl, bl on θl and α with the report's weight 13 on α.
      The core has no configuration for this experiment; it is simulated
      EXACTLY with the ``lateral`` kernel at e = 0 and x = y = 0 (with e = 0 the
      lateral equations are homogeneous in x, y, which then stay 0 and the other
      equations reduce to (3.19), (3.20) with the bearing law).
3. ``lateral``: k, b, e, mt on r = √(x² + y²) (mr, the disc's mass, weighed).
4. ``torsional`` (brake on): Ts, Tc, ωs, δ, bb on several experiments at once
   (different initial windings α0), θl and α (weight 13).

Each stage is a :func:`fit_parameters` call (trf, bounds, DP5, batched
Jacobian).  Bearing, lateral and brake stages use multiple shooting (segments
re-started from the data).  The data's speeds at the segment starts (derivative
estimates, the multiple shooting's nuisance states) are fitted with the parameters
from the data's estimates (``refine_speeds``, on by default:
``fit_parameters(..., fit_speeds=True)``, as ``diagnose`` and ``identify --add-effect``
fit them; ``benchmarks/bench_staged_speeds.py`` measures both ways in one run).  On
20 s recordings at 250 Hz and 100 Hz it took the lower stage's common scale of Jl, kθ,
Tcl, bl from 0.3-0.7 % off (held) to 0.02-0.04 %, and lowered the brake stage's largest
error in three of four cases (raised it in one: the independent rig at 500 Hz, δ +0.3
to +2.1 %), at 4-6 times its time.  The speeds are *not* first refined for the start
values (as ``diagnose`` does from its near-nominal start): from guesses 15-30 % off,
that sent the brake stage on three 60 s recordings at 1 kHz to 27 times the held
fit's RSS in 40 evaluations; from the data's estimates it converges there in 15, to
the held fit's result.  R² (report eq. 3.2) is computed on free runs from the data's
initial state, on estimation and validation data.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..configurations import Configuration
from ..errors import InputError
from ..io import TimeSeries
from ..params import IDX, RigParams
from .acting import check_fit_names
from .experiment import Experiment, prepare_experiment
from .fitting import FitResult, FitVariable, Objective, fit_parameters
from .metrics import r2
from .segmented import SegmentedModel

__all__ = [
    "StageResult",
    "IdentificationResult",
    "STAGES",
    "KTHETA_GEOMETRY",
    "bearing_experiment",
    "identify_stage",
    "identify_staged",
    "r2_free_run",
]

KTHETA_GEOMETRY = 0.0813  # N m/rad, from the string's geometry (report 3.3)
ALPHA_WEIGHT = 13.0  # report: weight factor on alpha against theta_l (Ju ≈ 13 Jl)


@dataclass(frozen=True)
class _Stage:
    name: str
    parameters: tuple[str, ...]
    weights: dict
    r2_channels: tuple[str, ...]
    segment_s: float | None
    fixed: dict = field(default_factory=dict)


STAGES: dict[str, _Stage] = {
    "upper": _Stage("upper", ("km", "Tcu", "dTcu", "bu", "dbu"), {"theta_u": 1.0}, ("theta_u",), None),
    "free_vibration": _Stage(
        "free_vibration", ("Jl", "bl", "Tcl"), {"theta_l": 1.0}, ("theta_l",), None, {"ktheta": KTHETA_GEOMETRY}
    ),
    "lower": _Stage(
        "lower", ("Jl", "ktheta", "Tcl", "bl"), {"theta_l": 1.0, "alpha": ALPHA_WEIGHT}, ("theta_l", "alpha"), 10.0
    ),
    "lateral": _Stage("lateral", ("k", "b", "e", "mt"), {"r": 1.0}, ("r",), 10.0),
    "brake": _Stage(
        "brake", ("Ts", "Tc", "ws", "delta", "bb"), {"theta_l": 1.0, "alpha": ALPHA_WEIGHT}, ("theta_l", "alpha"), 4.0
    ),
}

_STAGE_CONFIG = {
    "upper": Configuration.UPPER,
    "free_vibration": Configuration.FREE_VIBRATION,
    "lower": Configuration.LATERAL,
    "lateral": Configuration.LATERAL,
    "brake": Configuration.TORSIONAL,
}


def bearing_experiment(ts: TimeSeries, compare_rate_hz: float = 100.0) -> Experiment:
    """A recording of the torsional system without brake as an experiment of the lateral kernel.

    Lateral motion held: the ``lateral`` kernel reproduces it exactly with e = 0 (see the module docstring).

    Parameters
    ----------
    ts : TimeSeries
        The recording.
    compare_rate_hz : float, optional
        Comparison grid rate (Hz).  Default 100.

    Returns
    -------
    Experiment
        The experiment.
    """
    ex = prepare_experiment(
        ts, Configuration.TORSIONAL if ts.configuration is None else ts.configuration, compare_rate_hz=compare_rate_hz
    )
    ex.config = Configuration.LATERAL
    ex.meas.pop("x", None)
    ex.meas.pop("y", None)
    ex.name = f"{ex.name} (torsional, brake off)"
    return ex


@dataclass
class StageResult:
    """One stage: the fit and R² per channel on estimation and validation data."""

    name: str
    fit: FitResult
    r2_estimation: dict[str, float]
    r2_validation: dict[str, float]

    def to_json(self) -> dict:
        return {
            "stage": self.name,
            "values": self.fit.values,
            "std": self.fit.std,
            "r2_estimation": self.r2_estimation,
            "r2_validation": self.r2_validation,
            "warnings": self.fit.warnings,
            "nfev": self.fit.nfev,
        }


@dataclass
class IdentificationResult:
    """All stages and the final parameter set."""

    params: RigParams
    stages: list[StageResult]

    @property
    def warnings(self) -> list[str]:
        return [f"{s.name}: {w}" for s in self.stages for w in s.fit.warnings]

    def to_json(self) -> dict:
        return {"params": self.params.to_dict(), "stages": [s.to_json() for s in self.stages]}


#: the configuration each stage's recordings must have (the lower stage: the torsional system, brake off)
_RECORDING_CONFIG = {
    "upper": Configuration.UPPER,
    "free_vibration": Configuration.FREE_VIBRATION,
    "lower": Configuration.TORSIONAL,
    "lateral": Configuration.LATERAL,
    "brake": Configuration.TORSIONAL,
}
_STAGE_WHAT = {
    "upper": "the upper part alone (string disconnected)",
    "free_vibration": "the free-vibration release test (upper disc clamped)",
    "lower": "the torsional system with the brake off",
    "lateral": "the lateral configuration (brake off, lateral motion free)",
    "brake": "the torsional system with the brake on",
}


def _check_recording(d, stage: str) -> None:
    """Refuse a recording of another configuration than the stage's (a fit of the wrong equations)."""
    want = _RECORDING_CONFIG[stage]
    if isinstance(d, Experiment):
        ok = (Configuration.LATERAL, Configuration.TORSIONAL) if stage == "lower" else (want,)
        got, name = d.config, d.name
    elif isinstance(d, TimeSeries):
        ok, got, name = (want,), d.configuration, d.source
    else:
        raise InputError(f"stage {stage!r}: expected a TimeSeries or an Experiment, got {type(d).__name__}")
    if got is not None and got not in ok:
        raise InputError(
            f"stage {stage!r}: {name} is a recording of configuration {got.label}; the stage needs "
            f"{_STAGE_WHAT[stage]}, configuration {want.label}"
        )


def _as_experiments(data, stage: str, compare_rate_hz: float) -> list[Experiment]:
    if data is None:
        return []
    if isinstance(data, (TimeSeries, Experiment)):
        data = [data]
    data = list(data)
    for d in data:
        _check_recording(d, stage)
    out = []
    for d in data:
        if isinstance(d, Experiment):
            out.append(d)
        elif stage == "lower":
            out.append(bearing_experiment(d, compare_rate_hz))
        else:
            out.append(prepare_experiment(d, _STAGE_CONFIG[stage], compare_rate_hz=compare_rate_hz))
    return out


def _stage_params(params: RigParams, stage: _Stage) -> RigParams:
    p = params.replace(**stage.fixed) if stage.fixed else params
    return p


def r2_free_run(
    experiments: Sequence[Experiment], params: RigParams, channels: Sequence[str], fixed: dict | None = None
) -> dict[str, float]:
    """R² per channel (report eq. 3.2) of free runs from each recording's initial state.

    Parameters
    ----------
    experiments : sequence of Experiment
        The recordings.
    params : RigParams
        The parameters.
    channels : sequence of str
        The channels.
    fixed : dict, optional
        Parameters held at other values.

    Returns
    -------
    dict of str to float
        R² per channel.
    """
    if not experiments:
        return {}
    vec = params.to_vector()
    for n, v in (fixed or {}).items():
        vec[getattr(IDX, n)] = v
    model = SegmentedModel(list(experiments), None)
    pred = model.predict(vec[None, :], tuple(channels))[0]
    model.check_finite("R² of a free run")
    out = {}
    for c in channels:
        ys, yh = [], []
        for k, ex in enumerate(experiments):
            if c in pred.outputs[k]:
                ys.append(ex.channel(c))
                yh.append(pred.stitched(k, c))
        if ys:
            out[c] = r2(np.concatenate(ys), np.concatenate(yh))
    return out


def identify_stage(
    stage: str,
    estimation,
    params: RigParams,
    validation=None,
    *,
    compare_rate_hz: float = 100.0,
    max_nfev: int = 40,
    parameters: Sequence[str] | None = None,
    refine_speeds: bool = True,
) -> StageResult:
    """Run one stage of the procedure.

    Parameters
    ----------
    stage : str
        ``upper``, ``free_vibration``, ``lower``, ``lateral`` or ``brake``.
    estimation : TimeSeries, Experiment or a sequence of them
        The stage's recordings.
    params : RigParams
        The current parameter set (earlier stages' results, initial guesses for this one).
    validation : TimeSeries, Experiment or a sequence of them, optional
        Validation recordings.
    compare_rate_hz : float, optional
        Comparison grid rate (Hz).  Default 100.
    max_nfev : int, optional
        Least-squares evaluations.  Default 40.
    parameters : sequence of str, optional
        The parameters fitted (default: the stage's).
    refine_speeds : bool, optional
        Fit the segment-start speeds with the parameters (module docstring); False: hold them at the data's
        estimates.  Default True.

    Returns
    -------
    StageResult
        The stage's fit and R².

    Raises
    ------
    InputError
        An unknown stage, no estimation data, a recording of another configuration than the stage's, or
        a parameter that does not act in it.
    FitError
        The fitted model gives non-finite states on a recording (no R²).
    """
    if stage not in STAGES:
        raise InputError(f"unknown identification stage {stage!r}; expected one of: {', '.join(STAGES)}")
    st = STAGES[stage]
    check_fit_names(
        parameters or (), _RECORDING_CONFIG[stage], option=f"stage {stage!r}: parameter", brake=stage != "lower"
    )
    est = _as_experiments(estimation, stage, compare_rate_hz)
    val = _as_experiments(validation, stage, compare_rate_hz)
    if not est:
        raise InputError(f"stage {stage!r}: no estimation data")
    start = _stage_params(params, st)
    fixed = {"e": 0.0} if stage == "lower" else {}
    if fixed:
        start = start.replace(**fixed)
    names = list(parameters or st.parameters)
    variables = []
    for n in names:
        v = FitVariable.relative(start, n, 0.3, 3.0)
        if n == "dTcu":
            v = FitVariable(n, start.dTcu, -0.5 * start.Tcu, 0.5 * start.Tcu, 0.05 * start.Tcu)
        elif n == "dbu":
            v = FitVariable(n, start.dbu, -0.5 * start.bu, 0.5 * start.bu, 0.05 * start.bu)
        elif n == "delta":
            v = FitVariable(n, start.delta, 0.5, 6.0, 1.0)
        elif n == "Tc":
            v = FitVariable(n, start.Tc, 0.2 * start.Tc, min(3 * start.Tc, start.Ts), start.Tc)
        variables.append(v)
    model = SegmentedModel(est, st.segment_s)
    obj = Objective(model, st.weights)
    # the segment-start speeds fitted with the parameters from the data's estimates (not refined for the
    # start values first: speeds fitted to guesses 15-30 % off sent the brake stage's fit astray)
    res = fit_parameters(obj, start, variables, max_nfev=max_nfev, fit_speeds=bool(refine_speeds and st.segment_s))
    final = res.params.replace(e=params.e) if fixed else res.params
    r2e = r2_free_run(est, final, st.r2_channels, fixed)
    r2v = r2_free_run(val, final, st.r2_channels, fixed)
    res.params = final
    return StageResult(stage, res, r2e, r2v)


def identify_staged(
    data: dict[str, object],
    params: RigParams | None = None,
    *,
    validation: dict[str, object] | None = None,
    compare_rate_hz: float = 100.0,
    max_nfev: int = 40,
) -> IdentificationResult:
    """The full procedure: the stages that have recordings, in the report's order.

    Parameters
    ----------
    data : dict
        Stage name (see :data:`STAGES`) -> one recording or a list (the brake stage takes several, at
        different initial windings).
    params : RigParams, optional
        The initial guesses (default: the identified set of docs/model.md).
    validation : dict, optional
        Stage name -> validation recordings.
    compare_rate_hz : float, optional
        Comparison grid rate (Hz).  Default 100.
    max_nfev : int, optional
        Least-squares evaluations per stage.  Default 40.

    Returns
    -------
    IdentificationResult
        The final parameter set and each stage's fit, R² and identifiability warnings.

    Raises
    ------
    InputError
        An unknown stage name, or a recording of another configuration than its stage's (checked for every
        stage before any fit).
    FitError
        A stage's fitted model gives non-finite states on a recording.
    """
    unknown = set(data) - set(STAGES) | set(validation or {}) - set(STAGES)
    if unknown:
        raise InputError(f"unknown identification stage(s) {', '.join(sorted(unknown))}; expected: {', '.join(STAGES)}")
    for source in (data, validation or {}):
        for name, recs in source.items():
            for d in [recs] if isinstance(recs, (TimeSeries, Experiment)) else list(recs or []):
                _check_recording(d, name)
    p = params or RigParams()
    stages = []
    for name in STAGES:
        if name not in data:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sr = identify_stage(
                name, data[name], p, (validation or {}).get(name), compare_rate_hz=compare_rate_hz, max_nfev=max_nfev
            )
        p = sr.fit.params
        stages.append(sr)
    return IdentificationResult(p, stages)
