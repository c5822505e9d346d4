"""The candidate's own identification: its effect file added to the diagnosed model and fitted.

Discovery (:mod:`.discovery`) regresses the residual torques and writes the candidate as an effect file; whether
it explains the recording is decided the way ``drillgym identify --add-effect FILE:NAME`` would decide it: the
file's effect is added to the final model and its parameters are fitted by multiple shooting on the diagnosis'
own recordings, with the segments' start speeds, the base parameters as the diagnosis freed them (where it left
some at a bound, held at nominal and as diagnosed, the better fit kept).  Where the fit leaves the recording above
the noise, a freer fit is tried and kept when it counts by the selection's rules (:func:`_counts`): the base
parameters freed where they were held, then every selected library effect, and the one discovery named beside it,
freed (the selection ran before the candidate existed).  Every candidate is fitted through its group's terms
compiled once (:mod:`.group_terms`).  The answer is the residual against the noise with the candidate beside the
one without.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import Composition, Delay, Effect, Force, Input
from ..identification.fitting import FitResult, Objective
from .context import SelectionContext, base_at_bounds, converged_fit
from .criterion import plausible_prior, prior_cost
from .discovery_terms import dead_zone_variant
from .effects import get_effect
from .group_terms import file_name, terms_effect, write_candidate
from .results import Candidate, Diagnosis
from .scoring import score, significant
from .search_model import with_candidate
from .sensor_reading import MIN_READING_CUT, with_fitted_terms
from .state import Screening, transfer
from .unexplained import Unexplained, unexplained

__all__ = ["CandidateFit", "CandidateFitState", "fit_candidate", "choose_candidate", "screened_readings", "MAX_NFEV"]

#: least-squares evaluations of the candidate's fit
MAX_NFEV = 20
#: the base parameters a lateral force is fitted with, started from nominal (:func:`_stood_in`)
LATERAL_BASE = ("k", "b", "e")
#: least-squares evaluations of a reading's screen: its own parameters (and those of the library effects it may have
#: stood in for) fitted with the base parameters held as diagnosed, before a full fit frees them
SCREEN_NFEV = 5
#: a reading is fitted in full only when its screen removes at least this share of the unexplained variance (a
#: third of the bar it must meet to be kept, :data:`.sensor_reading.MIN_READING_CUT`)
SCREEN_CUT = 0.1


@dataclass
class CandidateFitState:
    """Where the candidate's fit ended, for fits that start from it (the lag it was found through, judged).

    Attributes
    ----------
    objective : Objective
        The objective fitted (its model holds the candidate, its segments' start speeds as fitted).
    composition : Composition
        The search model's composition with the candidate.
    result : FitResult
        The fit (vector, residual, RSS).
    fitted : list of str
        The candidate's parameters (their names in ``composition``).
    base_names : tuple of str
        The base parameters fitted with them (empty: held).
    nominal : numpy.ndarray
        The nominal vector of ``composition``.
    freeable : tuple of str
        The base parameters a later fit from here may free (every one: where the diagnosis left some at a
        bound, the effect it missed may have taken them there; a fit that ends at a bound does not count).
    regressed : dict of str to float
        The candidate's parameters as discovery regressed them, where its fit started (the fit may move them
        far to stand in for something else the model misses, a lag beside a dead zone).
    """

    objective: Objective
    composition: Composition
    result: FitResult
    fitted: list[str]
    base_names: tuple[str, ...]
    nominal: np.ndarray
    freeable: tuple[str, ...] = ()
    regressed: dict[str, float] = field(default_factory=dict)

    def context(self, base_names: tuple[str, ...], effects: dict[str, type[Effect]]) -> SelectionContext:
        """A fit context on the candidate's model from where its fit ended, its segments' start speeds its own.

        Parameters
        ----------
        base_names : tuple of str
            The base parameters a fit in it may free.
        effects : dict of str to Effect class
            The library's effects it may switch on or off, by name.

        Returns
        -------
        SelectionContext
            The context, on a copy of the objective with its own segment start speeds (fits in it leave
            this state's untouched).
        """
        obj = self.objective.with_own_speeds()
        return SelectionContext(
            obj, self.composition, np.asarray(self.result.vector), self.nominal, base_names, effects
        )


@dataclass
class CandidateFit:
    """The candidate fitted on the diagnosis' recordings.

    Attributes
    ----------
    values : dict of str to float
        Its fitted parameters.
    base_held : bool
        Whether the base parameters were held at their nominal values (the diagnosis left some at a bound).
    before, after : Unexplained
        The residual against the noise without and with the candidate.
    state : CandidateFitState or None
        Where the fit ended (not in the JSON).
    file_names : dict of str to str
        A fitted parameter's name -> its name in the candidate's file.
    base_fitted : dict of str to float
        The base parameters fitted with the candidate -> their change from nominal (%); empty: as diagnosed.
    with_library : tuple of str
        The library's effects fitted with it, ahead of it on the signal path (``motor_lag`` when its terms were
        found through a lag); their parameters are among ``values``.
    through : Effect class or None
        The compiled terms its fit ran through (:func:`.group_terms.terms_effect`; ``file_names`` maps their
        parameters to the file's), or None: through its own file.
    """

    values: dict[str, float]
    base_held: bool
    before: Unexplained
    after: Unexplained
    state: CandidateFitState | None = field(default=None, repr=False, compare=False)
    file_names: dict[str, str] = field(default_factory=dict)
    base_fitted: dict[str, float] = field(default_factory=dict)
    with_library: tuple[str, ...] = ()
    through: type[Effect] | None = field(default=None, repr=False, compare=False)

    def file_name(self, parameter: str) -> str:
        """The name a fitted parameter has in the candidate's file (its own name when it has none there)."""
        return self.file_names.get(parameter, parameter)

    @property
    def variance_cut(self) -> float:
        """Share of the residual's mean square (the unexplained variance, noise units²) the candidate removes."""
        b = self.before.ratio_to_noise**2
        return 1.0 - self.after.ratio_to_noise**2 / b if b > 0 else 0.0

    def to_json(self) -> dict:
        """``{values, base_held, ratio_before, ratio_after, variance_cut, verdict_after, channels_after,
        base_fitted_change_pct, with_library_effects}``."""
        return {
            "values": self.values,
            "base_held": self.base_held,
            "ratio_before": self.before.ratio_to_noise,
            "ratio_after": self.after.ratio_to_noise,
            "variance_cut": round(self.variance_cut, 4),
            "verdict_after": self.after.verdict,
            "channels_after": self.after.channels,
            "base_fitted_change_pct": {k: round(v, 3) for k, v in self.base_fitted.items()},
            "with_library_effects": list(self.with_library),
        }

    def line(self) -> str:
        """The fit in words."""
        vals = ", ".join(f"{k} = {v:.4g}" for k, v in self.values.items())
        base = "base held at nominal" if self.base_held else "base as diagnosed"
        if self.base_fitted:
            base = f"base parameters fitted with it: {moved_text(self.base_fitted) or 'none moved'}"
        if self.with_library:
            base = f"with the library's {' and '.join(self.with_library)} ahead of it; {base}"
        if self.variance_cut < 0.0:  # e.g. with the base held at nominal, where the diagnosis had it at a bound
            outcome = "it explains none of it: the model without it fits better"
        else:
            outcome = f"{self.variance_cut:.0%} of the unexplained variance removed"
        return (
            f"  its fit on this recording ({base}): {vals}; residual {self.before.ratio_to_noise:.3g} -> "
            f"{self.after.ratio_to_noise:.3g} times the noise ({outcome}; "
            f"{self.after.verdict.replace('_', ' ')} with it)"
        )


def fit_candidate(
    screening: Screening, diagnosis: Diagnosis, candidate: Candidate, noise_scales: dict[str, float]
) -> CandidateFit | None:
    """Fit a written candidate on the diagnosis' recordings (see the module docstring).

    Parameters
    ----------
    screening : Screening
        The recordings screened (their objective, its channels weighed by ``noise_scales``, :class:`_CandidateModel`).
    diagnosis : Diagnosis
        The diagnosis (final model, base decision, its residual against the noise).
    candidate : Candidate
        The candidate, with its effect file written (``effect_file``).
    noise_scales : dict of str to float
        The channels' noise (the objective's scales before any weighting).

    Returns
    -------
    CandidateFit or None
        The fit, or None when the candidate has no file or the diagnosis no final model.
    """
    if diagnosis.vector is None or diagnosis.composition is None:
        return None
    effect, start_values, is_terms = _effect_of(candidate)
    if effect is None:
        return None
    comp = diagnosis.composition
    ahead = _library_ahead(candidate)
    with_it = with_candidate(comp, diagnosis.model, ahead, effect)
    model = screening.model
    if ahead:  # the lag the terms were regressed through, fitted with them
        start_values = {**start_values, "tau_m": candidate.through_lag}
    names = list(start_values)
    setup = _CandidateModel(model, comp, with_it, effect, start_values, noise_scales, _stood_in(diagnosis, candidate))
    if diagnosis.at_bounds and diagnosis.nominal_vector is not None:
        # an effect the library lacks may have been absorbed at the bound: the base held at nominal, and held as
        # the diagnosis left it (its mismatch may be real: 5 % off beside an offset); the better fit is kept
        at_nominal, as_diagnosed = (
            setup.fit(_offset_start(candidate, comp, base), ()) for base in (diagnosis.nominal_vector, diagnosis.vector)
        )
        held = at_nominal[2].rss_after <= as_diagnosed[2].rss_after
        (obj, ctx, fit), start = (at_nominal, diagnosis.nominal_vector) if held else (as_diagnosed, diagnosis.vector)
        base_names = ()
    else:
        held, start = False, diagnosis.vector
        base_names = tuple(model.base_names) if diagnosis.base_off else ()
        obj, ctx, fit = setup.fit(_offset_start(candidate, comp, start), base_names)
    (obj, ctx, fit), base_names, held = _base_freed_if_needed(setup, (obj, ctx, fit), base_names, held, noise_scales)
    rest = _selected_rest(diagnosis, setup.library, candidate.beside)
    if rest and not unexplained(obj, np.asarray(fit.vector), noise_scales).explained:
        # every effect the selection took may have stood in for the candidate, which did not exist then (a 0.13 V
        # drive offset taken as a brake asymmetry of 0.40 / 1.08 beside the rig's 0.20 / 0.25): fitted again from
        # the start with them freed, kept where that counts by the selection's rules
        freer = replace(setup, library=(*setup.library, *rest))
        first = freer.fit(_offset_start(candidate, comp, start), base_names)
        alt, alt_base, alt_held = _base_freed_if_needed(freer, first, base_names, held, noise_scales)
        if _counts(fit, alt[2], len(rest) + len(alt_base) - len(base_names), alt[1]):
            (obj, ctx, fit), base_names, held = alt, alt_base, alt_held
    before = diagnosis.unexplained or unexplained(model.obj, diagnosis.vector, noise_scales)
    after = unexplained(obj, np.asarray(fit.vector), noise_scales)
    file_names = {n: file_name(candidate, n) for n in names}
    values = {file_names[n]: float(fit.vector[with_it.param_index(n)]) for n in names}
    state = CandidateFitState(obj, with_it, fit, names, base_names, ctx.nominal, tuple(model.base_names), start_values)
    moved = change_pct(with_it, fit.vector, ctx.nominal, base_names)
    through = effect if is_terms else None
    return CandidateFit(
        values, held, before, after, state, file_names, base_fitted=moved, with_library=tuple(ahead), through=through
    )


def _offset_start(candidate: Candidate, comp: Composition, vec: np.ndarray) -> np.ndarray:
    """``vec`` with its LVDT offset at the constant force beside the candidate's terms over k (``vec`` itself without
    either): started as diagnosed, the offset holds the constant part of the force (a brake pad's friction's mean)
    and the fit settles between the two (a 2.25 N pad: 30 % of the unexplained variance removed; from here 97.6 %)."""
    force = candidate.constant_force
    if force is None or "lvdt_offset" not in comp.names:
        return vec
    out = np.array(vec, dtype=float)
    k = float(out[comp.param_index("k")])
    for name, f in zip(("lvdt_x0", "lvdt_y0"), force, strict=True):
        out[comp.param_index(name)] += f / k
    return out


@dataclass(frozen=True)
class _CandidateModel:
    """The diagnosed model with the candidate (and the library's effects ahead of it) added, ready to fit."""

    model: Any  # the screening's search model
    comp: Composition  # the diagnosed model's composition
    with_it: Composition  # ... with the candidate
    effect: type[Effect]  # the candidate's effect
    start_values: dict[str, float]  # its free parameters' start
    # the channels' noise the fit weighs them by, as the candidate is judged (not the selection's weighting by the
    # sensors' misfit: there a quadratic drag's LVDTs counted 11 times less than the encoders and its fit traded the
    # drag for b at its bound, 6.6 -> 5.3 noise units on the LVDTs; on the noise, 0.18)
    scales: Mapping[str, float]
    library: tuple[str, ...] = ()  # the selected library effects' parameters fitted with it
    max_nfev: int = MAX_NFEV  # least-squares evaluations

    def fit(self, base: np.ndarray, base_names: tuple[str, ...]) -> tuple[Objective, SelectionContext, FitResult]:
        """The candidate's parameters and the base parameters ``base_names`` fitted from the model vector ``base``
        (the others held there), the segments' start speeds free."""
        start = transfer(base, self.comp, self.with_it)
        for p in self.effect.parameters:
            start[self.with_it.param_index(p.name)] = p.neutral if p.neutral is not None else p.guess
        for name, value in self.start_values.items():
            start[self.with_it.param_index(name)] = value
        obj = self.model.obj.with_own_speeds()
        obj.scales = dict(self.scales)
        obj.model = obj.model.with_composition(self.with_it)
        nominal = transfer(self.model.nominal, self.comp, self.with_it)
        for name in self.library:
            if name in LATERAL_BASE:  # from nominal: the diagnosis may have left it at a bound, standing in
                start[self.with_it.param_index(name)] = nominal[self.with_it.param_index(name)]
        ctx = SelectionContext(obj, self.with_it, start, nominal, base_names, {})
        names = list(dict.fromkeys([*self.start_values, *self.library, *base_names]))
        return obj, ctx, converged_fit(ctx, start, names, self.max_nfev)


def _stood_in(diagnosis: Diagnosis, candidate: Candidate) -> tuple[str, ...]:
    """The parameters fitted with the candidate because they may have stood in for it.

    A sensor's reading: the parameters of the library effects the diagnosis selected (a drift for an encoder's
    scale error, the twist it misreads growing with the angle turned; they go back towards neutral once it is in).
    A lateral force: the lateral base parameters :data:`LATERAL_BASE` (started from nominal, :class:`_CandidateModel`)
    and the selected lateral effects' parameters: the diagnosis pushed k and b to the bounds of their range to take
    a stiffening spring or a drag, and held there they leave the force's terms a fraction of its size.  A change of
    the motor's voltage: the selected effects on the same signal path (Input, Delay: a lag, a delay), which took
    what of it they could (a 0.36 V dead zone on steps was selected as a 200 ms input delay beside 24 ms; held
    there, the voltage terms' fit stopped at 29 % of the unexplained variance, freed 100 % with the delay back at
    23.5 ms).  Empty for the other candidates of the residual torques (their terms were regressed beside them)."""
    if diagnosis.composition is None:
        return ()
    if candidate.is_reading:
        return _selected_params(diagnosis)
    if candidate.is_lateral_force:
        return (*LATERAL_BASE, *_selected_params(diagnosis, lambda e: issubclass(e, Force) and e.acts_on == "lateral"))
    if candidate.group == "motor_voltage":
        return _selected_params(diagnosis, lambda e: issubclass(e, (Input, Delay)))
    return ()


def _selected_params(diagnosis: Diagnosis, keep=lambda effect: True, also: Sequence[str] = ()) -> tuple[str, ...]:
    """The parameters of the library effects selected (or named in ``also``) that ``keep`` accepts, in the
    diagnosed composition's order."""
    chosen = {*diagnosis.selected, *also}
    return tuple(p.name for e in diagnosis.composition.effects if e.name in chosen and keep(e) for p in e.parameters)


def _library_ahead(candidate: Candidate) -> dict[str, type[Effect]]:
    """The library's effects fitted ahead of the candidate on the signal path: ``motor_lag`` when its terms were
    regressed through a lag (:attr:`~.results.Candidate.through_lag`)."""
    return {"motor_lag": get_effect("motor_lag")} if candidate.through_lag is not None else {}


def change_pct(comp: Composition, vector, nominal: np.ndarray, names) -> dict[str, float]:
    """Parameters' change from nominal (%) in a vector of ``comp`` (those with a nominal value of 0 left out)."""
    out = {}
    for n in names:
        i = comp.param_index(n)
        if nominal[i] != 0.0:
            out[n] = 100.0 * (float(vector[i]) / nominal[i] - 1.0)
    return out


def moved_text(changes: dict[str, float]) -> str:
    """``km -2.9 %, Jl +4.1 %`` for the changes (%) of at least 0.05 %."""
    return ", ".join(f"{k} {v:+.1f} %" for k, v in changes.items() if abs(v) >= 0.05)


def _effect_of(candidate: Candidate) -> tuple[type[Effect] | None, dict[str, float], bool]:
    """The effect the candidate is fitted through, the start of its free parameters, and whether that effect is
    its group's terms compiled once (:func:`.group_terms.terms_effect`) rather than the candidate's own file
    (None: not written)."""
    through = terms_effect(candidate)
    if through is not None:
        return (*through, True)
    if candidate.effect_file is None:
        return None, {}, False
    effect = get_effect(candidate.effect_file)
    return effect, {p.name: p.guess for p in effect.parameters}, False


def _base_freed_if_needed(
    setup: _CandidateModel, fitted: tuple, base_names: tuple[str, ...], held: bool, noise_scales: dict[str, float]
) -> tuple[tuple, tuple[str, ...], bool]:
    """The fit ``fitted`` (objective, context, result) again with every base parameter freed, where they were held,
    it leaves the recording above the noise and that counts (:func:`_counts`: a km 3 % off beside a 0.1 V offset
    leaves hundreds of noise units); the fit kept, its freed base parameters and whether the base stayed held."""
    obj, ctx, fit = fitted
    if base_names or unexplained(obj, np.asarray(fit.vector), noise_scales).explained:
        return fitted, base_names, held
    every = tuple(setup.model.base_names)
    obj = ctx.obj.with_own_speeds()
    vec = np.asarray(fit.vector)
    free = SelectionContext(obj, ctx.comp, vec, ctx.nominal, every, {})
    res = converged_fit(free, vec, list(dict.fromkeys([*setup.start_values, *setup.library, *every])), MAX_NFEV)
    return ((obj, free, res), every, False) if _counts(fit, res, len(every), free) else (fitted, base_names, held)


def _counts(fit: FitResult, more: FitResult, extra: int, ctx: SelectionContext) -> bool:
    """Whether the fit ``more``, with ``extra`` parameters freed beside those of ``fit``, counts by the selection's
    rules (:func:`.scoring.significant`) with its freed base "a few percent off": none at a bound, their prior's
    cost within its 95 % quantile (a 31 ms lag beside a −0.12 V offset was taken by km, Tcu, bu, Ts, Tc 8-15 % low)."""
    ids = ctx.obj.channel_ids
    sc, _ = score(fit.residual, more, extra, channels=ids, blocks=ctx.obj.block_ids)
    if not significant(sc, fit.rss_after, more.rss_after, len(more.residual), fit.residual, more.residual, ids):
        return False
    vec = np.asarray(more.vector)
    if base_at_bounds(ctx, vec):
        return False
    base = tuple(ctx.base_names)
    return not base or prior_cost(ctx.comp, ctx.nominal, base, vec) <= plausible_prior(base)


def _selected_rest(diagnosis: Diagnosis, fitted: Sequence[str], beside: Sequence[str] = ()) -> tuple[str, ...]:
    """The parameters of the library effects selected, or named ``beside`` the candidate, that its fit held."""
    return tuple(n for n in _selected_params(diagnosis, also=beside) if n not in set(fitted))


def choose_candidate(
    screening: Screening,
    diagnosis: Diagnosis,
    noise_scales: dict[str, float],
    candidate_out: str | Path | None,
    readings: Sequence[Candidate] = (),
) -> Candidate | None:
    """The discovered candidate fitted, or its motor-side alternative, or a sensor's reading, whichever fit
    removes most.

    The motor side's candidate is fitted first (its terms are compiled once); when it leaves the recording at the
    noise, the other is not fitted.  The sensors' readings (:mod:`.sensor_reading`) are screened, and those that
    pass fitted, when neither leaves the recording at the noise; the reading whose fit removes most is kept when it
    removes more than theirs and at least :data:`.sensor_reading.MIN_READING_CUT` of the unexplained variance.  The
    candidate kept is the one written to ``candidate_out``; the best of the others is its
    :attr:`~.results.Candidate.alternative`.

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis, with its candidate (:func:`.discovery.discover`; None: only the readings are tried).
    noise_scales : dict of str to float
        The channels' noise.
    candidate_out : str or path or None
        Where the kept candidate's effect file goes.
    readings : sequence of Candidate, optional
        The sensors' readings (:func:`.sensor_reading.reading_candidates`; empty: none tried).

    Returns
    -------
    Candidate or None
        The candidate kept, with its fit; None when there was none and no reading's fit removes enough.
    """
    discovered = cand = diagnosis.candidate
    keep = other = None
    if cand is not None:
        keep, other = _discovered(screening, diagnosis, cand, noise_scales)
    if readings and (keep is None or keep.fit is None or not keep.fit.after.explained):
        reading = _best_reading(screening, diagnosis, readings, noise_scales)
        bar = max(_cut(keep), MIN_READING_CUT) if keep is not None else MIN_READING_CUT
        if reading is not None and _cut(reading) > bar:
            keep, other = reading, keep
        elif reading is not None and (other is None or _cut(reading) > _cut(other)):
            other = reading
    if keep is None:
        return None
    if keep is not discovered and candidate_out is not None:  # the file written holds the discovered candidate
        write_candidate(keep, candidate_out)
    keep.alternative = other
    return keep


def _best_reading(
    screening: Screening, diagnosis: Diagnosis, readings: Sequence[Candidate], noise_scales: dict[str, float]
) -> Candidate | None:
    """Every reading that passes its screen fitted: the one whose fit removes most, or, among those that leave the
    recording at the noise, the one that moved fewest base parameters with it, and the least (RMS of their change,
    %); None when no reading passes its screen.

    A reading is screened first (:func:`_screen_cut`) and fitted with the base parameters freed only when the screen
    removes at least :data:`SCREEN_CUT` of the unexplained variance: a channel left above the noise by a torque the
    model misses is no sensor's fault, and its reading's full fit costs as much as the candidate's.  All that pass
    are fitted, even after one reaches the noise: a scale error of one encoder reads nearly as the opposite error
    of the other with every angle rescaled (the motor encoder's +1 % as the lower's −1 % with the inertias and the
    motor constant 1 % off), which the base parameters freed beside the wrong one take up."""
    passed = screened_readings(screening, diagnosis, readings, noise_scales)
    for reading in passed:
        reading.fit = fit_candidate(screening, diagnosis, reading, noise_scales)
        with_fitted_terms(reading)
    return max(passed, key=_reading_rank) if passed else None


def screened_readings(
    screening: Screening, diagnosis: Diagnosis, readings: Sequence[Candidate], noise_scales: dict[str, float]
) -> list[Candidate]:
    """The sensors' readings whose screen (:func:`_screen_cut`) removes at least :data:`SCREEN_CUT` of the
    unexplained variance: those a full fit may keep.

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis.
    readings : sequence of Candidate
        The readings (:func:`.sensor_reading.reading_candidates`).
    noise_scales : dict of str to float
        The channels' noise.

    Returns
    -------
    list of Candidate
        The readings that pass, in their order.
    """
    return [r for r in readings if _screen_cut(screening, diagnosis, r, noise_scales) >= SCREEN_CUT]


def _screen_cut(
    screening: Screening, diagnosis: Diagnosis, reading: Candidate, noise_scales: dict[str, float]
) -> float:
    """The share of the unexplained variance a reading removes in a short fit (:data:`SCREEN_NFEV` evaluations) of
    its own parameters and of the library effects it may have stood in for, the base parameters held as
    diagnosed (-1 when the diagnosis has no final model)."""
    effect, start_values, _ = _effect_of(reading)
    comp, before = diagnosis.composition, diagnosis.unexplained
    if effect is None or comp is None or diagnosis.vector is None or before is None or before.ratio_to_noise <= 0:
        return -1.0
    with_it = with_candidate(comp, diagnosis.model, {}, effect)
    library = _stood_in(diagnosis, reading)
    setup = _CandidateModel(screening.model, comp, with_it, effect, start_values, noise_scales, library, SCREEN_NFEV)
    obj, _, fit = setup.fit(diagnosis.vector, ())
    after = unexplained(obj, np.asarray(fit.vector), noise_scales)
    return 1.0 - (after.ratio_to_noise / before.ratio_to_noise) ** 2


def _reading_rank(cand: Candidate) -> tuple[bool, int, float, float]:
    """A reading's rank (larger is better): at the noise with it; then fewest base parameters fitted with it and
    their smallest change (RMS, %); then its cut."""
    fit = cand.fit
    if fit is None:
        return False, 0, 0.0, -1.0
    if not fit.after.explained:
        return False, 0, 0.0, fit.variance_cut
    moved = len(fit.state.base_names) if fit.state is not None else 0
    change = float(np.sqrt(np.mean(np.square(list(fit.base_fitted.values()))))) if fit.base_fitted else 0.0
    return True, -moved, -change, fit.variance_cut


def _discovered(
    screening: Screening, diagnosis: Diagnosis, cand: Candidate, noise_scales: dict[str, float]
) -> tuple[Candidate, Candidate | None]:
    """The discovered candidate and its motor-side alternative fitted: (the one whose fit removes more, the
    other); the other is not fitted when the motor side's leaves the recording at the noise."""
    alt, cand.alternative = cand.alternative, None
    if alt is None:
        return _fitted_form(screening, diagnosis, cand, noise_scales), None
    alt = _fitted_form(screening, diagnosis, alt, noise_scales)
    if alt.fit is not None and alt.fit.after.explained:
        return alt, cand
    cand = _fitted_form(screening, diagnosis, cand, noise_scales)
    return (alt, cand) if _cut(alt) > _cut(cand) else (cand, alt)


def _cut(cand: Candidate) -> float:
    """The share of the unexplained variance the candidate's fit removes (-1 without a fit)."""
    return cand.fit.variance_cut if cand.fit is not None else -1.0


def _fitted_form(
    screening: Screening, diagnosis: Diagnosis, cand: Candidate, noise_scales: dict[str, float]
) -> Candidate:
    """The candidate fitted, or its dead-zone reading (:func:`.discovery.dead_zone_variant`) when that one's fit
    removes more of the unexplained variance (the other is not kept)."""
    cand.fit = fit_candidate(screening, diagnosis, cand, noise_scales)
    cand = _lag_that_counts(screening, diagnosis, cand, noise_scales)
    if cand.fit is None or cand.fit.after.explained:
        return cand
    variant = dead_zone_variant(cand, np.concatenate([ex.u_value for ex in screening.exps]))
    if variant is None:
        return cand
    variant.fit = fit_candidate(screening, diagnosis, variant, noise_scales)
    variant = _lag_that_counts(screening, diagnosis, variant, noise_scales)
    if variant.fit is not None and variant.fit.variance_cut > cand.fit.variance_cut:
        return variant
    return cand


def _lag_that_counts(
    screening: Screening, diagnosis: Diagnosis, cand: Candidate, noise_scales: dict[str, float]
) -> Candidate:
    """The candidate found through a lag (fitted with it), or the same terms fitted without the lag when the lag
    does not count against them (:func:`_counts`, one parameter more; nor a lag fitted below :data:`MIN_LAG_S`)."""
    if cand.through_lag is None or cand.fit is None or cand.fit.state is None:
        return cand
    plain = replace(cand, through_lag=None, fit=None)
    plain.fit = fit_candidate(screening, diagnosis, plain, noise_scales)
    if plain.fit is None or plain.fit.state is None:
        return cand
    with_lag, without = cand.fit.state, plain.fit.state
    vec = np.asarray(with_lag.result.vector)
    ctx = SelectionContext(with_lag.objective, with_lag.composition, vec, with_lag.nominal, with_lag.base_names, {})
    tau = float(vec[with_lag.composition.param_index("tau_m")])
    return cand if _counts(without.result, with_lag.result, 1, ctx) and tau >= MIN_LAG_S else plain


#: a lag the candidate's terms were found through counts only when fitted at least this long (s): shorter, it is
#: no lag at the rates recorded (≤ 1 kHz), and the fit has taken it out
MIN_LAG_S = 1e-3
