"""One front from a recording to a model: :func:`identify`.

In the spirit of PySINDy's ``SINDy(...).fit(...)``: one call over pluggable parts, every route of
drillgym (``drillgym identify``, ``diagnose --model-out``, ``evaluate --identify``, ``rig tune``)
calls it, so one recording gives one model file whichever route a user takes.

1. **diagnose** (:func:`drillgym.diagnosis.diagnose`): screen, select the library's effects, check,
   report; with ``discover``, a candidate effect outside the library from the residual, kept when its
   own fit removes at least :data:`~drillgym.diagnosis.reselection.MIN_CANDIDATE_CUT` of the unexplained
   variance, and then the whole library selected again on the model that holds it, its parameters refitted
   with the base (:mod:`drillgym.diagnosis.reselection`: its residual hid the effects beside it, a lag
   beside a dead zone, a position friction beside a drive offset);
2. **refit everything jointly**: the base parameters the configuration excites and every effect
   parameter fitted together, with their standard errors; where the selection took one of a motor lag
   and an input delay, the model with both is fitted too and kept when it removes clearly more;
3. the :class:`~drillgym.model.Model`, with its provenance (the recording's content hash, the settings),
   and what the final model still leaves unexplained (:class:`Identified`).

    >>> from drillgym import identify
    >>> found = identify("recording.csv")            # doctest: +SKIP
    >>> found.model.save("model.json")               # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FitError, InputTypeError
from .io import TimeSeries
from .model import Model, Provenance, as_model
from .params import RigParams

__all__ = ["IdentifyOptions", "Identified", "identify", "TIMING_EFFECTS"]

#: the signal path's timing effects the selection may take one of
TIMING_EFFECTS = ("motor_lag", "input_delay")
#: share of the residual sum of squares the fit with both must remove to replace the fit with one
BOTH_TIMING_GAIN = 0.05
#: share of the residual sum of squares a kept candidate's other reading must remove to replace it
#: (:mod:`.diagnosis.other_reading`)
OTHER_READING_GAIN = 0.05
#: where the fit with both starts: this share of the one's time as the lag, the rest as the delay
LAG_SHARE = 0.7


@dataclass(frozen=True)
class IdentifyOptions:
    """The identification's settings (every route passes the same defaults).

    Attributes
    ----------
    config : str or None
        The configuration when the recording's metadata has none.
    start : Model, str, path or None
        The model to start from (its base parameters as nominal, its effects held in the model and
        refitted); None: the model page's base parameters, no effect.
    discover : bool
        Look for an effect outside the library in the residual and keep it when it earns its place.
    candidate_out : str, path or None
        Where a discovered candidate's effect file goes (None: beside the recording, or a temporary
        folder for a recording in memory).
    compare_rate_hz : float
        Comparison grid of the diagnosis and the fit (Hz).
    max_nfev : int
        Least-squares evaluations of the final joint fit.
    fixed_base : bool
        Hold the base parameters at the start model's.
    candidates : sequence or None
        The library effects the selection may take (names, file specs or Effect classes); None: the
        library's for the configuration.
    segment_s : float or None
        Multiple-shooting segment length of the diagnosis (s); -1: the configuration's default; None: one
        free run.
    max_candidates : int
        Candidates outside the library found in turn (:class:`~drillgym.diagnosis.DiagnosisOptions`).  Default 1.
    """

    config: str | None = None
    start: Any = None
    discover: bool = True
    candidate_out: str | Path | None = None
    compare_rate_hz: float = 50.0
    max_nfev: int = 30
    fixed_base: bool = False
    candidates: Any = None
    segment_s: float | None = -1.0
    max_candidates: int = 1

    def to_json(self) -> dict[str, Any]:
        """The settings recorded in the model's provenance (paths left out: they differ between routes)."""
        return {
            "discover": self.discover,
            "compare_rate_hz": self.compare_rate_hz,
            "max_nfev": self.max_nfev,
            "fixed_base": self.fixed_base,
            "candidates": None if self.candidates is None else [getattr(c, "name", c) for c in self.candidates],
            "segment_s": self.segment_s,
            "max_candidates": self.max_candidates,
        }


@dataclass(frozen=True)
class Identified:
    """What :func:`identify` made of a recording.

    Attributes
    ----------
    model : Model
        The identified model: base parameters, effects (the library's and a kept candidate), values,
        standard errors, provenance.
    diagnosis : Diagnosis
        The first diagnosis (selection, checks, the candidate and its fit).
    reselection : Diagnosis or None
        The library selected again with the candidates in the model, the last of them (None: no candidate kept).
    selected : tuple of str
        The library effects in the model.
    discovered : tuple of str
        The kept candidates' effect file specs (``path.py:NAME``), in the order they were found.
    residual_to_noise : dict of str to float
        Per channel, the final model's RMS error over the recording's noise level (1: at the noise).
    warnings : tuple of str
        The diagnosis's and the fit's warnings, and the identification's notes.
    seconds : float
        Wall-clock time (s).
    fit : RefitResult or None
        The final joint fit: the error per channel before (the start model) and after, R², the fitted values.
    """

    model: Model
    diagnosis: Any
    reselection: Any
    selected: tuple[str, ...]
    discovered: tuple[str, ...]
    residual_to_noise: dict[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    seconds: float = 0.0
    fit: Any = field(default=None, repr=False, compare=False)

    @property
    def unexplained(self) -> Any:
        """The last diagnosis's account of the residual left (:class:`~drillgym.diagnosis.unexplained.Unexplained`)."""
        return (self.reselection or self.diagnosis).unexplained

    def lines(self) -> list[str]:
        """The identification in words."""
        m = self.model
        eff = ", ".join(f"{k} = {v:.4g}" for k, v in m.values.items()) or "none"
        out = [f"identified model: {m.label} ({eff})"]
        for spec in self.discovered:
            out.append(f"  with the candidate {spec.rsplit(':', 1)[1]} ({spec.rsplit(':', 1)[0]})")
        enc = m.encoders
        if enc is not None and enc.counts_per_rev is not None:
            noise = f", {enc.angle_noise * 1e3:.3g} mrad of noise after the count" if enc.angle_noise > 0 else ""
            out.append(f"  encoders: {enc.counts_per_rev} counts/rev{noise} (told to the controllers built on it)")
        elif enc is not None:
            out.append(f"  encoders: on no lattice of counts, {enc.angle_noise * 1e3:.3g} mrad of reading noise")
        if self.residual_to_noise:
            res = ", ".join(f"{c} {r:.3g}" for c, r in self.residual_to_noise.items())
            out.append(f"  residual left, times the noise: {res}")
        out += [f"warning: {w}" for w in self.warnings]
        return out


def recording_hash(recording: TimeSeries) -> str:
    """SHA-256 of a recording's columns (names and float64 bytes, sorted by name): the same whether it was read
    from a file or made in memory."""
    h = hashlib.sha256()
    for name in sorted(recording.columns):
        h.update(name.encode())
        h.update(np.ascontiguousarray(recording.columns[name], dtype=np.float64).tobytes())
    return h.hexdigest()


def identify(recording: TimeSeries | str | Path, options: IdentifyOptions | None = None, **settings: Any) -> Identified:
    """Identify a recording's model: diagnose, discover, select again with the candidate, refit jointly.

    Parameters
    ----------
    recording : TimeSeries, str or path
        The recording (a file in the data format of docs/data_format.md, or one read).
    options : IdentifyOptions, optional
        The settings (default: :class:`IdentifyOptions` ()).
    **settings
        Fields of :class:`IdentifyOptions`, overriding ``options``.

    Returns
    -------
    Identified
        The model and what was found.

    Raises
    ------
    InputError
        A recording or setting that cannot be used (one line naming it).
    """
    from dataclasses import fields, replace

    from .diagnosis import DiagnosisOptions, diagnose
    from .diagnosis.reselection import kept_in_turn
    from .identification.reading_noise import recording_encoders

    unknown = sorted(set(settings) - {f.name for f in fields(IdentifyOptions)})
    if unknown:
        valid = ", ".join(f.name for f in fields(IdentifyOptions))
        raise InputTypeError(f"identify: unknown setting(s) {', '.join(unknown)}; the settings are {valid}")
    o = replace(options or IdentifyOptions(), **settings)
    ts = _recording(recording)
    start_time = time.perf_counter()
    start = as_model(o.start, who="identify: start") if o.start is not None else Model()
    cand_out = _candidate_out(o, ts)
    base = DiagnosisOptions(
        base_effects=list(start.composition.effects) or None,
        effect_params=dict(start.values) or None,
        compare_rate_hz=o.compare_rate_hz,
        fixed_base=o.fixed_base,
        effects=o.candidates,
        segment_s=o.segment_s,
        discover=o.discover,
        candidate_out=cand_out,
        max_candidates=o.max_candidates,
    )
    d = diagnose(ts, start.params, o.config, options=base)
    _log("diagnosis", start_time)
    last = d.final()  # the library selected again with each kept candidate in the model, in turn
    reselection = last if last is not d else None
    kept = kept_in_turn(d)
    specs, values, params = _selected(last, kept)
    notes: list[str] = []
    held = tuple(n for k in kept for n in k.held_terms)
    comp, fitted, res = _joint_fit(ts, last, params, specs, values, o, notes, held)
    kept, (comp, fitted, res), notes = _other_readings(
        ts, last, params, specs, values, o, kept, (comp, fitted, res), notes
    )
    _log("joint fit", start_time)
    std = {k: v for k, v in res.std.items() if math.isfinite(v)}
    comp, fitted, std = _in_files(comp, fitted, std, kept)
    all_fitted = set(fitted)
    comp, fitted, std = _without_idle_effects(comp, fitted, std, notes)
    left_out = all_fitted - set(fitted)  # the fit's words on them are of a model no longer returned
    prov = Provenance(
        route="identify",
        recording=Path(ts.source).name if ts.source else None,
        recording_sha256=recording_hash(ts),
        settings=o.to_json(),
        version=_version(),
    )
    model = Model(res.params, tuple(comp.effects), fitted, std, prov, recording_encoders(ts, start.encoders))
    ratios = {c: float(res.rms_after[c] / n) for c, n in (res.noise or {}).items() if c in res.rms_after and n > 0}
    names = [e.name for e in comp.effects]
    selected = tuple(n for n in names if _is_library(comp, n))
    cand_specs = tuple(k.spec for k in kept)
    fit_words = [w for w in res.warnings if w.split(":")[0] not in left_out]
    warnings = tuple([w for step in d.in_turn() for w in step.warnings] + fit_words + notes)
    return Identified(
        model,
        d,
        reselection,
        selected,
        cand_specs,
        ratios,
        tuple(dict.fromkeys(warnings)),
        time.perf_counter() - start_time,
        res,
    )


def _recording(recording: Any) -> TimeSeries:
    if isinstance(recording, TimeSeries):
        return recording
    if isinstance(recording, (str, Path)):
        from .io import read_timeseries

        return read_timeseries(recording)
    raise InputTypeError(f"identify: the recording must be a TimeSeries or a file path, got {type(recording).__name__}")


def _candidate_out(o: IdentifyOptions, ts: TimeSeries) -> Path | None:
    if not o.discover:
        return None
    if o.candidate_out is not None:
        return Path(o.candidate_out)
    src = Path(ts.source) if ts.source and not ts.source.startswith("<") else None
    if src is not None and src.parent.is_dir():
        return src.with_name(src.stem + "_candidate.py")
    import tempfile

    return Path(tempfile.mkdtemp(prefix="drillgym_candidate_")) / "candidate.py"


def _selected(d: Any, kept: list[Any]) -> tuple[list[Any], dict[str, float], RigParams]:
    """The effects (specs, or the compiled terms a kept candidate's fit ran through), values and base parameters
    of a diagnosis's selected model."""
    params, records, _ = d.selected_model()
    through = {k.through.name: k.through for k in kept if k.through is not None}
    specs = [through.get(r["name"], r["spec"]) for r in records]
    values = {k: v for r in records for k, v in r["values"].items()}
    return specs, values, params


def _in_files(comp: Any, values: dict[str, float], std: dict[str, float], kept: list[Any]):
    """The composition, values and standard errors with each kept candidate's file in place of the compiled terms
    its fit ran through (the same function; the terms it does not use left out)."""
    from .diagnosis.effect_file import covering_file
    from .diagnosis.effects import get_effect
    from .effects import Composition

    for k in kept:
        if k.through is not None and k.through.name in comp.names:
            values, std = k.in_file(values), k.in_file(std)
            spec = covering_file(k.candidate, values) if k.candidate is not None else k.spec
            file_effect = get_effect(spec)
            comp = Composition(tuple(file_effect if e is k.through else e for e in comp.effects))
    return comp, values, std


#: share of a parameter's range within which a fitted value counts as its neutral one (:func:`_without_idle_effects`)
NEUTRAL_TOLERANCE = 1e-9


def _without_idle_effects(comp: Any, values: dict[str, float], std: dict[str, float], notes: list[str]):
    """The composition, values and standard errors without the effects the fit left doing nothing: every parameter
    at its declared neutral value (an input delay fitted to 0 s, the bound, where the joint fit of a lag and a
    delay moved the whole time into the lag).  The model's runs are the same; a consumer no longer carries an
    effect that is not there (a controller would run a delay line of no length)."""
    from .effects import Composition

    idle = []
    for e in comp.effects:
        neutral = e.neutral_values()
        if neutral is None:
            continue
        ranges = {p.name: p.hi - p.lo for p in e.parameters}
        if all(abs(values[n] - v) <= NEUTRAL_TOLERANCE * max(ranges[n], 1.0) for n, v in neutral.items()):
            idle.append(e)
    if not idle:
        return comp, values, std
    names = {p.name for e in idle for p in e.parameters}
    for e in idle:
        shown = ", ".join(f"{p.name} = {values[p.name]:.3g} {p.unit}" for p in e.parameters)
        notes.append(f"{e.name} fitted to where it does nothing ({shown}): left out of the model")
    kept = Composition(tuple(e for e in comp.effects if e not in idle))
    return kept, {k: v for k, v in values.items() if k not in names}, {k: v for k, v in std.items() if k not in names}


def _is_library(comp: Any, name: str) -> bool:
    e = next(e for e in comp.effects if e.name == name)
    return getattr(e, "__drillgym_file__", None) is None


def _joint_fit(ts, d, params, specs, values, o: IdentifyOptions, notes: list[str], held=(), also=None):
    """The model refitted jointly; with both timing effects when one was taken and both fit clearly better.

    Each fit runs on the diagnosis' search model (every library effect it tried, the others held at the values
    where they vanish exactly, :func:`._search_model_for`) wherever that holds the model's effects in the same
    order on the signal path: its runs equal the selected composition's to the bit, the kernels the diagnosis
    compiled serve the fit, and a new selection costs no compilation (about 20 s per composition on 2 cores).
    The model returned is the selected composition; ``held`` are its parameters held at ``values`` (the terms a
    kept candidate does not use); ``also``: another compiled model the fits may run on where the diagnosis' search
    model does not hold the effects (the one a candidate ranked second was fitted in)."""
    from .diagnosis.refit import refit
    from .diagnosis.search_model import BASE_FREE, neutral_values
    from .effects import compose

    search = d.composition

    def fit(specs: list[str], values: dict[str, float]):
        comp, vals = compose(specs, {k: v for k, v in values.items() if k in _param_names(specs)})
        free = [] if o.fixed_base else list(BASE_FREE[d.config])
        runs_on, start = comp, vals
        on_search = _search_model_for(search, comp) or _search_model_for(also, comp)
        if on_search is not None:  # the effects not selected where they vanish, whatever the search left them at
            off = [e for e in on_search.effects if e.name not in comp.names]
            runs_on, start = on_search, {**neutral_values(off), **vals}
        res = refit(
            ts,
            params,
            o.config,
            base_effects=runs_on,
            base_values=start,
            fit=free + [n for n in comp.effect_param_names if n not in held],
            refit_base=False,
            compare_rate_hz=o.compare_rate_hz,
            max_nfev=o.max_nfev,
        )
        return comp, {**vals, **{k: v for k, v in res.values.items() if k in vals}}, res

    if not specs and o.fixed_base:
        raise FitError("identify: nothing to fit (no effect selected and the base parameters held)")
    best = fit(specs, values)
    both = _with_both_timing_effects(specs, values)
    if both is not None:
        other = fit(*both)
        ss, ss2 = _sum_of_squares(best[2]), _sum_of_squares(other[2])
        if ss2 < (1.0 - BOTH_TIMING_GAIN) * ss:
            best = other
            notes.append(
                f"a motor lag and an input delay fitted together: residual {ss2:.4g} against {ss:.4g} noise units²"
            )
    return best


def _other_readings(ts, d, params, specs, values, o: IdentifyOptions, kept: list, best: tuple, notes: list[str]):
    """The kept candidates each read the other way where that fits the whole model better
    (:func:`.diagnosis.other_reading.readings_of`: a dead zone for an offset, or the converse, the other encoder's
    scale error, the candidate its own fit ranked second), and then the library effects selected beside the first
    reading earned again (:func:`_library_earned`): the candidates, the joint fit and its notes."""
    from dataclasses import replace

    from .diagnosis.other_reading import other_reading, readings_of

    kept, specs, reread = list(kept), list(specs), False
    for i, k in enumerate(kept):
        queue = readings_of(k)
        while queue:
            other = queue.pop(0)
            trial_kept = [*kept[:i], other.kept, *kept[i + 1 :]]
            held = tuple(n for t in trial_kept for n in t.held_terms)
            trial_specs = [other.kept.through if s is kept[i].through else s for s in specs]
            trial_notes: list[str] = []
            start = {**values, **other.kept.through_values}
            trial = _joint_fit(ts, d, params, trial_specs, start, o, trial_notes, held, other.fitted_in)
            ss, ss2 = _sum_of_squares(best[2]), _sum_of_squares(trial[2])
            if ss2 < (1.0 - OTHER_READING_GAIN) * ss:
                line = (
                    f"the candidate read the other way, with the terms {', '.join(other.candidate.terms)}, fits the "
                    f"whole model better: residual {ss2:.4g} against {ss:.4g} noise units²"
                )
                written = other.write(trial[1], f"{line} (drillgym identify; its values are that fit's)")
                kept[i], best, specs, reread = written, trial, trial_specs, True
                notes = [*trial_notes, line]
                if other.ranked_second:  # the alternative took the place: its own other readings next
                    more = (other_reading(other.kept), other_reading(other.kept, shared_at_zero=True))
                    queue += [replace(r, fitted_in=other.fitted_in) for r in more if r is not None]
    if reread:
        best = _library_earned(ts, d, params, o, kept, best, notes)
    return kept, best, notes


def _library_earned(ts, d, params, o: IdentifyOptions, kept: list, best: tuple, notes: list[str]) -> tuple:
    """With a candidate read another way (:func:`_other_readings`), each library effect of the model, selected
    beside the first reading, refitted without it and left out where it removes less than
    :data:`OTHER_READING_GAIN` of the residual (a brake asymmetry and a friction drift the first selection took for a
    lower encoder's scale error, kept beside the encoder's reading): the joint fit kept; ``notes`` says so."""
    from .effects import LIBRARY

    held = tuple(n for k in kept for n in k.held_terms)
    for effect in [e for e in best[0].effects if LIBRARY.get(e.name) is e]:
        specs = [e for e in best[0].effects if e is not effect]
        trial_notes: list[str] = []
        trial = _joint_fit(ts, d, params, specs, best[1], o, trial_notes, held)
        ss, ss2 = _sum_of_squares(best[2]), _sum_of_squares(trial[2])
        if ss2 < (1.0 + OTHER_READING_GAIN) * ss:
            best = trial
            notes += [
                *trial_notes,
                f"{effect.name} left out: beside the candidate read the other way it removes less than "
                f"{OTHER_READING_GAIN:.0%} of the residual ({ss2:.4g} without it, {ss:.4g} with it, in noise units²)",
            ]
    return best


def _search_model_for(search: Any, comp: Any) -> Any:
    """The diagnosis' search model without the effects that do not vanish exactly at their neutral values (a
    0.1 ms motor lag), when it holds every effect of ``comp`` in the same order on the signal path; else None.

    Its runs then equal ``comp``'s to the bit (the other effects add exactly nothing), and its kernels are
    compiled already."""
    from .diagnosis.search_model import vanishes_exactly
    from .effects import Composition

    if search is None or not set(comp.names) <= set(search.names):
        return None
    kept = Composition(tuple(e for e in search.effects if e.name in comp.names or vanishes_exactly(e)))
    return kept if kept.signal_path(among=comp.names) == comp.signal_path() else None


def _param_names(specs: list[str]) -> set[str]:
    from .effects import compose

    return {p.name for e in compose(specs)[0].effects for p in e.parameters}


def _with_both_timing_effects(specs: list[str], values: dict[str, float]) -> tuple[list[str], dict] | None:
    """The model with a lag and a delay when the selection took one of them (else None): the one's time split,
    :data:`LAG_SHARE` to the lag, the lag first on the signal path.

    The selection tells a lag from a delay on the comparison grid, where the two shift the slow response alike;
    a plant with both (or with the other one) is then read as one element of about their sum and the base
    parameters absorb the difference as a common scale (a plant with a 46 ms lag and a 17 ms delay read as a
    56 ms delay, km -4.0 %; fitted with both, a 63 ms lag, km -0.02 %)."""
    taken = [s for s in specs if s in TIMING_EFFECTS]
    if len(taken) != 1:
        return None
    total = values.get("tau_m", values.get("delay"))
    if total is None or not total > 0:
        return None
    rest = [s for s in specs if s not in TIMING_EFFECTS]
    return ["motor_lag", "input_delay", *rest], {**values, "tau_m": LAG_SHARE * total, "delay": (1 - LAG_SHARE) * total}


def _sum_of_squares(res) -> float:
    """The fit's residual: the sum over channels of the squared RMS in noise units (each channel's RMS over the
    recording's noise on it), so an LVDT's metres and an encoder's radians count alike; a channel without a noise
    estimate counts in its own unit."""
    noise = getattr(res, "noise", None) or {}
    return float(sum((v / noise[c]) ** 2 if noise.get(c, 0.0) > 0 else v * v for c, v in res.rms_after.items()))


def _version() -> str:
    from . import __version__

    return __version__


def _log(step: str, since: float) -> None:
    import logging

    logging.getLogger("drillgym.identify").info("%s done at %.1f s", step, time.perf_counter() - since)
