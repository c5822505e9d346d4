"""The whole library selected again with a discovered candidate in the model.

A candidate effect outside the library (a dead zone, a voltage offset, cogging) leaves, before it is found, a
residual of up to thousands of noise units.  Beside it the library's effects change that residual by a small
fraction, so the first selection, which scores them against the model *without* the candidate, takes none of
them, or one that imitates part of the candidate (a friction drift for an offset).  Once the candidate's own
fit removes at least :data:`MIN_CANDIDATE_CUT` of the unexplained variance, the diagnosis runs again on the
model that holds it: every library effect screened, selected, checked and reported by the same rules, with the
candidate's parameters freed wherever the base parameters are (its first fit bent its terms to stand in for
what was missing beside it: a dead zone's width fitted 0.66 V for 0.36 V beside a position friction, which the
selection then found once both were fitted together).

The model run again holds the candidate as its fit ran: through its group's compiled terms (:mod:`.group_terms`;
the terms it does not use held at 0), whose kernels serve every recording, where the candidate's own file, holding
only the terms chosen for this recording, would be a new compiled model each time (26-29 s on 2 cores).
:func:`drillgym.identify` writes the model with the file in their place: the same function.

One mechanism for every kind: a lag or a delay beside a motor-side candidate, a position friction or a string
damping beside a dead zone, an effect the first selection took that no longer counts (it is simply not selected
again).  The final model is never clearly worse than the candidate's own fit: where the selection run again ends
beyond :data:`WORSE_BY` times its residual (a brake pad beside the anisotropy, which the run again did not take:
35 noise units for the fit's 2.1), the library effects the candidate's fit held are held beside it and refitted
(``hold_selected``), and the better of the two kept.  The pipeline stores the result as
:attr:`~.results.Diagnosis.reselection`; :func:`drillgym.identify` builds its model from it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import Effect
from ..params import N_PARAMS, RigParams
from .candidate import Candidate
from .effect_file import covering_file
from .effects import EFFECTS, effects_for, get_effect
from .results import Diagnosis
from .state import DiagnosisOptions

__all__ = [
    "MIN_CANDIDATE_CUT",
    "WORSE_BY",
    "KeptCandidate",
    "kept_candidate",
    "kept_in_turn",
    "next_candidate_out",
    "reselection_inputs",
    "worse_than_candidate",
]

#: share of the unexplained variance a candidate's own fit must remove to enter the model (the bar a sensor's
#: reading meets to be kept, :data:`.sensor_reading.MIN_READING_CUT`): a candidate that removes
#: less earns no place in the model a user builds on
MIN_CANDIDATE_CUT = 0.3
#: the diagnosis run again ends clearly worse than the candidate's own fit beyond this factor on the residual RMS
#: (noise units): then the model the candidate was fitted in is held and refitted
WORSE_BY = 1.5


@dataclass(frozen=True)
class KeptCandidate:
    """A candidate that entered the model.

    Attributes
    ----------
    spec : str
        Its effect file spec (``path.py:NAME``).
    values : dict of str to float
        Its fitted parameters (their names in the file), and those of the library effects fitted with it.
    ahead : tuple of str
        The library effects it was fitted with, ahead of it on the signal path (a lag its terms were found
        through).
    through : Effect class or None
        The compiled terms its fit ran through (:func:`.group_terms.terms_effect`), which the diagnosis run again
        holds in its place: the same function, with kernels compiled once for every recording, where the file's
        coefficients make a new compiled model each time.  None: the file itself is held.
    through_values : dict of str to float
        Every parameter of ``through`` as its fit left it (the terms it does not use at 0).
    file_names : dict of str to str
        A parameter of ``through`` the candidate uses -> its name in the file.
    candidate : Candidate or None
        The candidate its file was written from (None: a library effect discovery named).
    base : RigParams or None
        The base parameters its fit ended at, where it freed them (its values hold only beside them: a brake
        pad's friction fitted with the lateral stiffness 7 % up); None: the diagnosis' own.
    fitted_values : dict of str to float
        Every effect parameter of the model its fit ran in (the first selection's effects too), as it left them.
    fitted_with : tuple of str
        The library effects that model held away from their neutral values: the first selection's, and those the
        fit freed beside the candidate (a lateral anisotropy a brake pad's terms had stood in for).
    """

    spec: str
    values: dict[str, float]
    ahead: tuple[str, ...]
    through: type[Effect] | None = None
    through_values: dict[str, float] = field(default_factory=dict)
    file_names: dict[str, str] = field(default_factory=dict)
    candidate: Candidate | None = None
    base: RigParams | None = None
    fitted_values: dict[str, float] = field(default_factory=dict)
    fitted_with: tuple[str, ...] = ()

    @property
    def held_terms(self) -> tuple[str, ...]:
        """The parameters of ``through`` the candidate does not use (held at their values)."""
        return tuple(n for n in self.through_values if n not in self.file_names)

    def in_file(self, values: Mapping[str, float]) -> dict[str, float]:
        """Values of ``through``'s parameters (and any others) by the names the file gives them, its unused
        terms left out."""
        unused = set(self.held_terms)
        return {self.file_names.get(k, k): v for k, v in values.items() if k not in unused}


def kept_candidate(diagnosis: Diagnosis) -> KeptCandidate | None:
    """The diagnosis' candidate when it enters the model, else None.

    Parameters
    ----------
    diagnosis : Diagnosis
        A diagnosis with discovery.

    Returns
    -------
    KeptCandidate or None
        The candidate, when it has an effect file and its fit removes at least :data:`MIN_CANDIDATE_CUT`.
    """
    c = diagnosis.candidate
    if c is None or c.fit is None or not c.effect_file or c.fit.variance_cut < MIN_CANDIDATE_CUT:
        return None
    values = {c.fit.file_name(k): v for k, v in c.fit.values.items()}
    ahead = tuple(c.fit.with_library)
    through, state = c.fit.through, c.fit.state
    base = _fitted_base(state)
    fitted = state.composition.named(state.result.vector) if state is not None else {}
    effects = {k: v for k, v in fitted.items() if k in set(state.composition.effect_param_names)} if fitted else {}
    more = {"base": base, "fitted_values": effects, "fitted_with": _fitted_with(state, diagnosis, fitted)}
    if through is None or state is None:
        return KeptCandidate(covering_file(c, values), values, ahead, candidate=c, **more)
    own = {p.name for p in through.parameters}
    names = {k: v for k, v in c.fit.file_names.items() if k in own}
    if set(names.values()) != {p.name for p in get_effect(c.effect_file).parameters}:  # hold the file itself
        return KeptCandidate(covering_file(c, values), values, ahead, candidate=c, **more)
    through_values = {n: float(fitted[n]) for n in own}
    return KeptCandidate(c.effect_file, values, ahead, through, through_values, names, c, **more)


def _fitted_with(state, diagnosis: Diagnosis, fitted: Mapping[str, float]) -> tuple[str, ...]:
    """The library effects of the model a candidate's fit ran in that it held: the diagnosis' selection, and those
    whose fitted values are away from their neutral ones."""
    if state is None:
        return tuple(diagnosis.selected)
    out = []
    for eff in state.composition.effects:
        neutral = eff.neutral_values() or {}
        away = any(abs(fitted[n] - v) > 1e-12 * max(1.0, abs(v)) for n, v in neutral.items() if n in fitted)
        if eff.name in diagnosis.selected or (away and eff.name in EFFECTS):
            out.append(eff.name)
    return tuple(out)


def _fitted_base(state) -> RigParams | None:
    """The base parameters a candidate's fit ended at, where it freed them (else None)."""
    if state is None or not state.base_names:
        return None
    return RigParams.from_vector(np.asarray(state.result.vector, dtype=float)[:N_PARAMS])


def worse_than_candidate(again: Diagnosis, diagnosis: Diagnosis) -> bool:
    """Whether the diagnosis run again with the candidate ends clearly worse than the candidate's own fit (its
    residual RMS more than :data:`WORSE_BY` times the fit's, in noise units): it lost an effect the model the
    candidate was fitted in held (a brake pad beside the anisotropy: 2.1 noise units with it, 35 without).

    Parameters
    ----------
    again : Diagnosis
        The diagnosis run again.
    diagnosis : Diagnosis
        The first diagnosis, with its kept candidate's fit.

    Returns
    -------
    bool
    """
    c = diagnosis.candidate
    if again.unexplained is None or c is None or c.fit is None:
        return False
    return again.unexplained.ratio_to_noise > WORSE_BY * c.fit.after.ratio_to_noise


def kept_in_turn(diagnosis: Diagnosis) -> list[KeptCandidate]:
    """The candidates that entered the model in turn (:meth:`~.results.Diagnosis.in_turn`).

    Parameters
    ----------
    diagnosis : Diagnosis
        The first diagnosis.

    Returns
    -------
    list of KeptCandidate
        In the order they were found.
    """
    return [k for step in diagnosis.in_turn()[:-1] if (k := kept_candidate(step)) is not None]


def reselection_inputs(
    diagnosis: Diagnosis,
    kept: KeptCandidate,
    options: DiagnosisOptions,
    left_out: Sequence[str] = (),
    library: bool = False,
    hold_selected: bool = False,
) -> tuple[RigParams, DiagnosisOptions]:
    """The base parameters and the options of the diagnosis run again with the candidate in the model.

    Parameters
    ----------
    diagnosis : Diagnosis
        The first diagnosis (its re-identified base parameters are the start, unless the candidate's fit freed
        them: then where that fit left them).
    kept : KeptCandidate
        The candidate.
    options : DiagnosisOptions
        The first diagnosis' options.
    left_out : sequence of str, optional
        Library effects not selected again nor held beside the candidate (a library lateral effect the residual
        said is another force, :func:`.lateral_library.library_versus_outside`).
    library : bool, optional
        ``kept`` is a library effect discovery named in a candidate's place (:mod:`.library_columns`): it takes
        no candidate's turn, so discovery runs again as it did here (another effect outside the library, e.g. a
        dead zone on the motor side beside the position friction named on the lower disc, is looked for on the
        residual of the model with it).  Default False.
    hold_selected : bool, optional
        Hold the library effects the candidate's fit held too (:attr:`KeptCandidate.fitted_with`, those in
        ``left_out`` as well), at the values it left them: the model the candidate was fitted in, refitted, where the
        selection run again from the model's own effects ended worse than the candidate's own fit
        (:func:`worse_than_candidate`).  Default False.

    Returns
    -------
    RigParams
        The base parameters to start from.
    DiagnosisOptions
        The model's own effects, the library effects fitted with the candidate, and the candidate, held in
        the model with their values and refitted with the base parameters; discovery of the next candidate
        while ``max_candidates`` allows one more (its file beside the first, :func:`next_candidate_out`).
    """
    from ..effects import compose

    first, values0 = compose(options.base_effects, options.effect_params)
    # held as the candidate's fit held them, left_out too: the model it was fitted in needed them (an anisotropy
    # the lateral verdict took for the brake pad's force)
    beside = [*(a for a in kept.ahead if a not in left_out), *(kept.fitted_with if hold_selected else ())]
    held = [*first.effects, *dict.fromkeys(a for a in beside if a not in first.names)]
    comp, _ = compose([*held, kept.through or kept.spec])
    names = set(comp.effect_param_names)
    fitted = kept.fitted_values if hold_selected else {}
    values: dict[str, Any] = {
        k: v for k, v in {**fitted, **values0, **kept.values, **kept.through_values}.items() if k in names
    }
    params = kept.base or (diagnosis.params if diagnosis.params is not None else RigParams())
    more = options.max_candidates > 1  # the next candidate is looked for on the residual of this model
    if library:
        turn = {"discover": options.discover, "candidate_out": options.candidate_out}
    else:
        turn = {
            "discover": more,
            "max_candidates": max(1, options.max_candidates - 1),
            "candidate_out": next_candidate_out(options.candidate_out) if more else None,
        }
    again = replace(
        options,
        base_effects=list(comp.effects),
        effect_params=values,
        **turn,
        refit_model_effects=True,
        held_effect_params=(*options.held_effect_params, *kept.held_terms),
    )
    if left_out:
        candidates = options.effects or effects_for(diagnosis.config)
        again = replace(again, effects=[e for e in candidates if get_effect(e).name not in left_out])
    return params, again


def next_candidate_out(path: str | Path | None) -> Path | None:
    """Where the next candidate's effect file goes: ``NAME_2.py`` beside ``NAME.py`` (``NAME_3.py`` beside
    ``NAME_2.py``); None for None.

    Parameters
    ----------
    path : str or path or None
        The file of the candidate found before.

    Returns
    -------
    pathlib.Path or None
        The file.
    """
    if path is None:
        return None
    path = Path(path)
    stem, _, count = path.stem.rpartition("_")
    if stem and count.isdigit():
        return path.with_name(f"{stem}_{int(count) + 1}{path.suffix}")
    return path.with_name(f"{path.stem}_2{path.suffix}")
