"""Every group's terms as one effect compiled once: what a candidate's fit and the diagnosis run again hold.

A candidate file holds only the terms discovery chose, so its compiled model would be new for nearly every
recording (26-29 s on 2 cores each time).  Its fit runs instead through the effect of its whole group, each term's
coefficient a parameter (0: off), the terms it does not use held at 0:

* the motor side and the sensors' readings: the library classes of :mod:`.motor_terms` and :mod:`.reading_terms`;
* every other group (the friction on either disc, the string, a torque on the lower disc, a lateral force): its
  term list (:mod:`.discovery_terms`, :mod:`.lateral_terms`) written once by the candidate files' own writer
  (:func:`.effect_file.write_effect_file`) with every term in, in the kernel cache's ``terms`` folder.  Only the
  candidate's coefficients and bounds change from one recording to the next, and the compiled model's key does not
  read them (:mod:`drillgym.effects.file_signature`): one compilation per group and machine.

:func:`terms_effect` gives the effect and where the candidate's terms start in it; :func:`terms_parameter` maps a
term's label to its parameter there, :func:`file_name` such a parameter to its name in the candidate's file, and
:func:`write_candidate` writes a fitted candidate's file with its values renamed so.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from functools import cache
from pathlib import Path

from ..effects import Effect
from ..effects.codegen import cache_root
from .discovery_terms import _groups
from .effect_file import write_effect_file
from .effects import get_effect
from .lateral_discovery import LATERAL_GROUP
from .lateral_terms import outside_terms
from .motor_terms import TERM_EFFECTS, WIDTH_PARAMETERS, term_parameters
from .results import Candidate

__all__ = ["terms_effect", "terms_parameter", "terms_name", "file_name", "write_candidate"]


@cache
def _group_terms(group: str) -> tuple[tuple[str, str, float], ...]:
    """A written group's terms as (label, code, value at rest), in the order of its list; empty for a group
    whose terms are a library class (:data:`.motor_terms.TERM_EFFECTS`) or unknown."""
    if group in TERM_EFFECTS:
        return ()
    if group == LATERAL_GROUP:  # a candidate holds outside terms only (the library's shapes are its effects')
        return tuple((t.label, t.code, 0.0) for t in outside_terms())
    return tuple((t.label, t.code, t.at_rest) for t in _groups(False).get(group, ()))


def terms_name(group: str) -> str:
    """The name of the effect a group's candidates are fitted through.

    Parameters
    ----------
    group : str
        The candidate's group.

    Returns
    -------
    str
        The library class's name for the motor side and the readings, else ``GROUP_terms``.
    """
    return TERM_EFFECTS[group].name if group in TERM_EFFECTS else f"{group}_terms"


def terms_parameter(group: str, label: str) -> str | None:
    """The parameter of a term in its group's effect (:func:`terms_effect`).

    Parameters
    ----------
    group : str
        The candidate's group.
    label : str
        The term's label.

    Returns
    -------
    str or None
        The parameter's name, or None when the group's effect has no such term.
    """
    if group in TERM_EFFECTS:
        return term_parameters(group, label)
    labels = [label for label, _, _ in _group_terms(group)]
    return f"{terms_name(group)}_c{labels.index(label) + 1}" if label in labels else None


def terms_effect(candidate: Candidate) -> tuple[type[Effect], dict[str, float]] | None:
    """The effect of a candidate's whole group and the start of the parameters its terms use.

    Parameters
    ----------
    candidate : Candidate
        The candidate.

    Returns
    -------
    tuple of (Effect class, dict of str to float) or None
        The effect and the candidate's coefficients (and scanned widths) by their parameters in it; None when a
        term of the candidate has no parameter there (its own file is then fitted).
    """
    group = candidate.group
    start = {}
    for label, c in candidate.terms.items():
        name = terms_parameter(group, label)
        if name is None:
            return None
        start[name] = c
        if label in candidate.widths:
            start[WIDTH_PARAMETERS[group]] = candidate.widths[label]
    if group in TERM_EFFECTS:
        return TERM_EFFECTS[group], start
    return get_effect(_written(candidate)), start


def _written(candidate: Candidate) -> str:
    """The spec of the group's effect written with the candidate's coefficients and bounds (every other term at
    0), in the kernel cache's ``terms`` folder under a digest of its text (written once)."""
    group = candidate.group
    terms = _group_terms(group)
    whole = Candidate(
        group,
        {label: candidate.terms.get(label, 0.0) for label, _, _ in terms},
        {label: code for label, code, _ in terms},
        {label: rest for label, _, rest in terms},
        candidate.explained,
        candidate.n_samples,
        reach={label: candidate.reach.get(label, 0.0) for label, _, _ in terms},
    )
    name = terms_name(group)
    folder = cache_root() / "terms"  # beside the kernel packages (pruning removes only those)
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        draft = write_effect_file(whole, Path(tmp) / f"{name}.py", name)
        text = draft.read_text(encoding="utf-8")
        path = folder / f"{name}_{hashlib.sha256(text.encode()).hexdigest()[:16]}.py"
        if not path.exists():
            os.replace(draft, path)
    return f"{path}:{name}"


def file_name(candidate: Candidate, parameter: str) -> str:
    """The name a fitted parameter has in the candidate's file (``NAME_c<i>``, ``NAME_w<i>``), or its own name."""
    if not candidate.name:
        return parameter
    for i, label in enumerate(candidate.terms, 1):
        if terms_parameter(candidate.group, label) == parameter:
            return f"{candidate.name}_c{i}"
        if parameter == WIDTH_PARAMETERS.get(candidate.group) and label in candidate.widths:
            return f"{candidate.name}_w{i}"
    return parameter


def write_candidate(cand: Candidate, candidate_out: str | Path) -> Candidate:
    """A fitted candidate other than discovery's with its effect file written to ``candidate_out`` (in place of
    discovery's), and its fit's values by the names its file gives them.

    Parameters
    ----------
    cand : Candidate
        The candidate (a sensor's reading, discovery's alternative).
    candidate_out : str or path
        Its effect file.

    Returns
    -------
    Candidate
        The same candidate, updated in place.
    """
    write_effect_file(cand, candidate_out)
    if cand.fit is not None:
        cand.fit.values = {file_name(cand, k): v for k, v in cand.fit.values.items()}
        cand.fit.file_names = {k: file_name(cand, k) for k in cand.fit.file_names}
    return cand
