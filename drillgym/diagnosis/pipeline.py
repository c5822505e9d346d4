"""The diagnosis as a pipeline: screen, select, check, report, discover.

1. :func:`.screening.screen` — the recording prepared and conditioned, the candidates it can show, the
   search model (every candidate at its neutral values); :func:`.detectability.detectability` — which effects
   and base parameters the recording's input can show at all, and which pairs it shows alike (one batched
   residual evaluation, no fit);
2. :func:`.orders.select` — the forward selection in several orders (:mod:`.forward`, :mod:`.backward`),
   the better model by the criterion (:mod:`.criterion`);
3. :func:`.checks.check` — position-dependent effects in both halves of the recording, a lag or a delay
   at the recording's own rate, a drift or a position friction on a disc that hardly turns;
4. :func:`.ranking.report` — the diagnosis: the ranking, the base parameters that moved, the warnings;
   :func:`.input_order.input_order` — two Input effects fitted in both orders, the better reported;
   :func:`.unexplained.unexplained` — the final residual against the noise, where it lives, what it depends on;
5. :func:`.discovery.discover` (with ``discover``) — a candidate effect outside the library from the
   residual torques of the (first) recording on its own samples up to 250 Hz, written as an effect file;
   :func:`.candidate_fit.choose_candidate` — the candidate (and the motor side's best beside it, and each
   sensor's reading where its channel stays above the noise, :mod:`.sensor_reading`) added to the final model and
   fitted; the one whose fit removes most is kept, its residual reported;
   :func:`.lateral_library.library_versus_outside` — a library lateral effect the selection took that the residual
   lateral force says is another force (a warning in words); :func:`.reading_in_place.reading_in_place` — where
   the selection took a library effect a sensor's reading draws as well (an LVDT's gain for
   ``lateral_anisotropy``, the lower encoder's zero for ``lvdt_skew``, an encoder's scale for ``friction_drift``),
   the reading fitted in its place, kept when it leaves clearly less than the effect and less than the candidate
   (the library selected again beside it decides whether the effect was there too);
6. :mod:`.reselection` — with a candidate kept in the model, the whole diagnosis again on the model that holds
   it (its parameters refitted with the base): the candidate's residual hid the library's effects beside it.  Up
   to ``max_candidates``, that diagnosis discovers again on its own residual: a second unknown effect (one in the
   drive, one in the string) is found once the first is in the model, and enters by the same bar.  A
   library lateral effect that the residual said is another force is not a candidate there: it is left out of
   the model the candidate enters.  Where that diagnosis ends clearly worse than the candidate's own fit
   (:func:`.reselection.worse_than_candidate`: it lost an effect the candidate's model held), it runs once more
   with the library effects the candidate's fit held beside it, and the better of the two is kept.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from ..configurations import Configuration
from ..errors import InputTypeError
from ..identification.blas import one_blas_thread
from ..identification.experiment import Experiment, prepare_experiment
from ..io import TimeSeries
from ..params import RigParams
from .candidate_fit import choose_candidate, screened_readings
from .checks import check
from .detectability import detectability
from .discovery import discover
from .effect_file import candidate_name
from .group_terms import terms_name, write_candidate
from .information import require_information
from .input_order import input_order
from .lateral_library import LateralVerdict, library_versus_outside
from .library_columns import LibraryAnswer, library_answer
from .orders import select
from .ranking import report
from .reading_in_place import ReadingVerdict, reading_in_place
from .reselection import KeptCandidate, kept_candidate, reselection_inputs, worse_than_candidate
from .results import Diagnosis
from .screening import screen
from .sensor_reading import reading_candidates
from .state import DiagnosisOptions
from .unexplained import unexplained

__all__ = ["DiagnosisOptions", "diagnose"]


def diagnose(
    data: TimeSeries | Experiment | Sequence[Experiment],
    params: RigParams | None = None,
    config: str | Configuration | None = None,
    *,
    options: DiagnosisOptions | None = None,
    **settings: Any,
) -> Diagnosis:
    """Which set of effects the recording shows, with the base parameters re-identified.

    Parameters
    ----------
    data : TimeSeries, Experiment or sequence of Experiment
        A recording or prepared experiments.
    params : RigParams, optional
        Nominal base parameters (default: the identified set of docs/model.md).
    config : str or Configuration, optional
        The configuration when the recording's metadata has none.
    options : DiagnosisOptions, optional
        The settings (default: :class:`DiagnosisOptions` ()).
    **settings
        Fields of :class:`DiagnosisOptions` (``effects``, ``base_effects``, ``effect_params``,
        ``segment_s``, ``compare_rate_hz``, ``lvdt_lowpass_hz``, ``refine_speeds``, ``fixed_base``,
        ``n_joint``, ``max_effects``, ``discover``, ``candidate_out``), overriding ``options``.

    Returns
    -------
    Diagnosis
        The effects selected, the ranking, the base parameters that moved, and (with ``discover``) a
        candidate effect outside the library or advice.

    Raises
    ------
    InputError
        An unknown candidate effect, or a recording without a configuration.
    InputTypeError
        A setting that is not a field of :class:`DiagnosisOptions` (also a :class:`TypeError`).
    CannotTellError
        A recording that cannot carry a verdict (the motor's disc does not turn): "cannot tell from this
        recording", with what would tell.

    Examples
    --------
    >>> from drillgym.diagnosis import diagnose
    >>> d = diagnose(recording)                          # doctest: +SKIP
    >>> d.selected, d.base_parameters                    # doctest: +SKIP
    """
    unknown = sorted(set(settings) - {f.name for f in fields(DiagnosisOptions)})
    if unknown:
        valid = ", ".join(f.name for f in fields(DiagnosisOptions))
        raise InputTypeError(f"diagnose: unknown setting(s) {', '.join(unknown)}; the settings are {valid}")
    if params is not None and not isinstance(params, RigParams):
        raise InputTypeError(f"params must be RigParams (None: the identified set), got {type(params).__name__}")
    opts = replace(options or DiagnosisOptions(), **settings)
    for rec in _recordings(data):  # no verdict from a recording that cannot carry one
        require_information(rec)
    with one_blas_thread():  # every step's threads (fits side by side, the lag/delay searches) see the same BLAS
        screening = screen(data, params, config, opts)
        noise = dict(screening.model.obj.scales)  # the selection may weight the sensors by their misfit
        shows = detectability(screening)  # in noise units: before the selection reweights the sensors
        outcome = check(screening, select(screening.model, opts.selection()), opts.selection())
        diagnosis = report(screening, outcome)
        diagnosis = replace(
            diagnosis,
            input_order=input_order(screening, diagnosis),
            unexplained=unexplained(screening.model.obj, diagnosis.vector, noise),
            detectability=shows,
        )
    if opts.discover and screening.config is not Configuration.UPPER:
        diagnosis, verdict, library = _discovered(screening, diagnosis, noise, opts)
        kept = kept_candidate(diagnosis) if library is None else KeptCandidate(library.effect, {}, ())
        if verdict is not None:  # said either way; left out of the model only where a candidate takes its place
            diagnosis = replace(diagnosis, warnings=[*diagnosis.warnings, verdict.line(left_out=kept is not None)])
        if kept is not None:
            left_out = (verdict.library,) if verdict is not None else ()
            inputs = (diagnosis, kept, opts, left_out)
            again, again_options = reselection_inputs(*inputs, library=library is not None)
            redo = diagnose(data, again, config, options=again_options)
            if library is None and worse_than_candidate(redo, diagnosis):  # the candidate's own model, refitted
                again, again_options = reselection_inputs(*inputs, hold_selected=True)
                held = diagnose(data, again, config, options=again_options)
                if _residual(held) < _residual(redo):
                    line = (
                        f"the library selected again beside the candidate left {_residual(redo):.3g} times the noise, "
                        f"its own fit {diagnosis.candidate.fit.after.ratio_to_noise:.3g}: the effects that fit held "
                        f"({', '.join(kept.fitted_with) or 'none'}) are held beside it ({_residual(held):.3g})"
                    )
                    redo = replace(held, warnings=[*held.warnings, line])
            diagnosis = replace(diagnosis, reselection=redo)
    return diagnosis


def _residual(d: Diagnosis) -> float:
    """A diagnosis' final residual RMS in noise units (infinite without one)."""
    return d.unexplained.ratio_to_noise if d.unexplained is not None else float("inf")


def _discovered(
    screening, diagnosis: Diagnosis, noise: dict[str, float], opts: DiagnosisOptions
) -> tuple[Diagnosis, LateralVerdict | None, LibraryAnswer | None]:
    """The diagnosis with a candidate effect outside the library (or advice), each candidate's own fit judged;
    the library lateral effect the residual says is another force, if any; and the library effect that explains
    the residual torques in the candidate's place (:mod:`.library_columns`), if any (then no candidate)."""
    fine = _fine(screening.exps[0])
    found, advice = discover(fine, diagnosis, opts.candidate_out)
    held = set(diagnosis.composition.names) if diagnosis.composition is not None else set()
    found = _not_held(found, held)  # a group found in turn once more is the first's terms again
    readings = [r for r in reading_candidates(diagnosis) if _not_held(r, held) is not None]
    library = library_answer(found)
    if library is not None and not _a_reading_shows(screening, diagnosis, readings, noise):
        # known physics the selection missed, and no sensor's reading for it (an encoder's scale error reads as a
        # torque growing along the run, as a friction drift's does; where one passes its screen, the readings and
        # the terms are fitted first, and the library effect is the answer where the terms win): no outside file
        return _library_named(diagnosis, library, found), None, library
    verdict = library_versus_outside(fine, diagnosis, found)  # a library lateral effect standing in for another
    first, diagnosis = diagnosis, replace(diagnosis, candidate=found, advice=advice)
    chosen = None
    with one_blas_thread():  # its own identification is part of the answer
        if found is not None or readings:
            chosen = choose_candidate(screening, diagnosis, noise, opts.candidate_out, readings)
        in_place = reading_in_place(screening, diagnosis, noise)  # a reading the library drew
        if in_place is not None and (chosen is None or chosen.fit is None or _leaves_more(chosen, in_place)):
            chosen = in_place.reading
            if opts.candidate_out is not None:  # its file in the place of the candidate's it beat
                write_candidate(chosen, opts.candidate_out)
            diagnosis = replace(diagnosis, warnings=[*diagnosis.warnings, in_place.line()])
    read = chosen is not None and chosen.is_reading
    if library is not None and chosen is not None and not read and chosen.group == found.group:
        # the readings fitted lost to the discovered terms, which the library effect explains: it is the answer
        return _library_named(first, library, chosen), None, library
    return replace(diagnosis, candidate=chosen, advice=[] if read else advice), verdict, None


def _library_named(diagnosis: Diagnosis, library: LibraryAnswer, candidate) -> Diagnosis:
    """The diagnosis with the library effect named in the candidate's place: the candidate's file removed, the
    answer among its warnings."""
    _remove_file(candidate)
    return replace(diagnosis, warnings=[*diagnosis.warnings, library.line()])


def _leaves_more(chosen, in_place: ReadingVerdict) -> bool:
    """Whether the candidate chosen leaves more than a reading in a library effect's place (residual RMS over every
    channel, noise units)."""
    return chosen.fit.after.ratio_to_noise > in_place.reading.fit.after.ratio_to_noise


def _a_reading_shows(screening, diagnosis: Diagnosis, readings: list, noise: dict[str, float]) -> bool:
    """Whether a sensor's reading passes its screen (then the readings and the candidate are fitted and compared,
    :func:`.candidate_fit.choose_candidate`, before any answer)."""
    if not readings:
        return False
    with one_blas_thread():
        return bool(screened_readings(screening, diagnosis, readings, noise))


def _remove_file(candidate) -> None:
    """Remove the effect file discovery wrote for a candidate that is not proposed (a library effect explains it)."""
    spec = candidate.effect_file if candidate is not None else None
    if spec:
        Path(spec.rpartition(":")[0] or spec).unlink(missing_ok=True)


def _not_held(candidate, held: set[str]):
    """The candidate (a copy without an alternative whose effect the model holds already); None when its own is
    held."""
    if candidate is None or _group_held(candidate.group, held):
        return None
    alternative = candidate.alternative
    if alternative is not None and _group_held(alternative.group, held):
        return replace(candidate, alternative=None)
    return candidate


def _group_held(group: str, held: set[str]) -> bool:
    """Whether the model holds a group's candidate: its file's effect, or the compiled terms a kept one's fit ran
    through (:attr:`.reselection.KeptCandidate.through`), which the diagnosis run again holds in its place."""
    return candidate_name(group) in held or terms_name(group) in held


def _recordings(data: Any) -> list[TimeSeries]:
    """The recordings behind what :func:`diagnose` is given (those it can reach)."""
    items = [data] if isinstance(data, (TimeSeries, Experiment)) else list(data)
    out = []
    for item in items:
        rec = item if isinstance(item, TimeSeries) else getattr(item, "recording", None)
        if rec is not None:
            out.append(rec)
    return out


def _fine(ex: Experiment) -> Experiment:
    """The experiment on its recording's own samples, up to 250 Hz (the discovery's grid); itself when it
    has no recording."""
    ts = ex.recording
    if ts is None:
        return ex
    return prepare_experiment(
        ts, ex.config, compare_rate_hz=min(250.0, ts.sample_rate_hz), lvdt_lowpass_hz=ex.lvdt_lowpass_hz
    )
