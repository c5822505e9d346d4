"""A kept candidate read another way, for the whole model to decide: a dead zone for an offset, the other encoder.

Where the command never turns the motor backwards, a negative offset ``-w`` and a dead zone of half-width ``w``
(``-sat(u, w)``) change the voltage at the motor alike wherever the command is above ``w``; inside, the motor
sees ``u - w`` (a voltage that brakes it) or nothing.  The candidate's own fit, on a model that may still lack
the lag and the friction beside it, cannot tell them apart (an independent plant's 0.4 V dead zone: both readings
removed 97.6 % of the unexplained variance), and the model a controller is built on must have the right one: an
observer on the offset read for that dead zone held nothing below 4 rad/s.

An encoder's reading has one too: a scale error k of one encoder reads nearly as −k / (1 + k) of the other with
every angle rescaled, which the base parameters freed beside it take up; what tells them apart (a position
friction that follows the lower disc's true angle, the motor's torque per true radian) shows only in the whole
model (a motor encoder 1.2 % off beside a position friction, read as the lower's −1.16 % with an offset of
−0.088 rad).  :func:`drillgym.identify` fits the other reading with the whole model (:func:`other_reading`) and
keeps the one that fits it better.

The same holds between a candidate and the one its own fit ranked second (:func:`alternative`: a sensor's reading
beside discovered terms): a motor encoder 1.5 % off beside string damping on the coupled rig, with a friction drift
in the first selection, was kept as a lower-disc torque growing with time (its own fit 95.6 % of the unexplained
variance, the lower encoder's reading 94.0 %), and the model file left 142 noise units on θu.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from ..effects import Composition
from .candidate import Candidate
from .discovery_terms import dead_zone_variant, offset_variant
from .effect_file import candidate_name, write_effect_file
from .group_terms import file_name, terms_parameter
from .motor_terms import WIDTH_PARAMETERS, term_parameters
from .reading_terms import SENSORS
from .reselection import MIN_CANDIDATE_CUT, KeptCandidate
from .sensor_reading import START_WIDTH_RAD_S, reading_candidate

__all__ = ["OtherReading", "other_reading", "alternative", "readings_of"]


@dataclass(frozen=True)
class OtherReading:
    """A kept candidate read the other way.

    Attributes
    ----------
    kept : KeptCandidate
        The other reading as a kept candidate, on the same compiled terms (its file not written yet).
    candidate : Candidate
        Its terms, as its file is written (:meth:`write`).
    fitted_in : Composition or None
        The compiled model its own fit ran in (the search model with its terms), where the diagnosis' search model
        does not hold them: the whole model's fits run there, compiled already.
    ranked_second : bool
        It is the kept candidate's alternative (:func:`alternative`), not a reading of the kept one.
    """

    kept: KeptCandidate
    candidate: Candidate
    fitted_in: Composition | None = None
    ranked_second: bool = False

    def write(self, values: Mapping[str, float] | None = None, note: str = "") -> KeptCandidate:
        """Write the other reading's file in the place of the first's (the same path).

        Parameters
        ----------
        values : mapping of str to float, optional
            The compiled terms' parameters as the whole model fitted them: the file's terms and width take them
            (default: its terms as they started).
        note : str, optional
            A line the file's docstring adds (what decided it).

        Returns
        -------
        KeptCandidate
            The kept candidate holding the file written.
        """
        cand = self.candidate
        if values:
            terms = {lb: values.get(terms_parameter(cand.group, lb) or "", v) for lb, v in cand.terms.items()}
            width = values.get(WIDTH_PARAMETERS.get(cand.group, ""))
            widths = {lb: width for lb in cand.widths} if width is not None else cand.widths
            cand = replace(cand, terms=terms, widths=widths)
        if note:
            cand = replace(cand, notes=(*cand.notes, note))
        path = Path(self.kept.spec.rpartition(":")[0])
        write_effect_file(cand, path, cand.name)
        return replace(self.kept, spec=cand.effect_file, candidate=cand)


def other_reading(kept: KeptCandidate, shared_at_zero: bool = False) -> OtherReading | None:
    """The kept candidate's other reading (module docstring), or None when it has none.

    Parameters
    ----------
    kept : KeptCandidate
        A candidate that entered the model, fitted through its group's compiled terms.
    shared_at_zero : bool, optional
        Start the terms both readings share at zero rather than at the kept candidate's fitted values: what
        the kept reading's shape needed of them may be no part of the other's (a 0.41 V dead zone read as
        −0.28 sign(u) + 0.067 u|u|: read again as a zone from the u|u| kept there, the joint fit stopped at a
        0.33 V zone beside it, leaving 2.6 times the residual of the mixed shift; the zone alone is the plant).

    Returns
    -------
    OtherReading or None
        The other reading, its terms started at the regressed values (the replaced term's parameter at 0 and
        held), the terms both share at the kept candidate's fitted values (or at zero).
    """
    c = kept.candidate
    if kept.through is None or c is None:
        return None
    if c.group in OTHER_ENCODER:
        return None if shared_at_zero else _other_encoder(kept)
    if c.group != "motor_voltage":
        return None
    other = dead_zone_variant(c) or offset_variant(c)
    if other is None:
        return None
    other = replace(other, name=c.name)
    names: dict[str, str] = {}
    start: dict[str, float] = {}
    for i, (label, value) in enumerate(other.terms.items(), 1):
        parameter = term_parameters(c.group, label)
        if parameter is None:
            return None
        names[parameter] = f"{c.name}_c{i}"
        shared = parameter in kept.file_names
        start[parameter] = (0.0 if shared_at_zero else kept.through_values.get(parameter, value)) if shared else value
        if label in other.widths:
            width = WIDTH_PARAMETERS[c.group]
            names[width] = f"{c.name}_w{i}"
            start[width] = other.widths[label]
    if shared_at_zero and not any(p in kept.file_names for p in names):
        return None  # no term both share: the same start as the other
    off = dict.fromkeys(kept.through_values, 0.0)  # the terms it does not use: off, and held there
    return OtherReading(replace(kept, through_values={**off, **start}, file_names=names), other)


#: an encoder's reading -> the other encoder's, which reads nearly alike with every angle rescaled
OTHER_ENCODER = {"motor_encoder": "lower_encoder", "lower_encoder": "motor_encoder"}


def _other_encoder(kept: KeptCandidate) -> OtherReading:
    """The other encoder's reading of a kept encoder reading: its scale error −k / (1 + k) for the kept one's k,
    its offset and play the kept one's with their sign turned, its play's width the same; the kept encoder's terms
    at 0 and held (both are terms of one compiled effect)."""
    this, that = SENSORS[kept.candidate.group], SENSORS[OTHER_ENCODER[kept.candidate.group]]
    values = kept.through_values
    scale = values.get(this.terms[this.symbol], 0.0)
    start = {this.terms[lb]: 0.0 for lb in this.terms}
    start[that.terms[that.symbol]] = -scale / (1.0 + scale)
    start[that.terms["1"]] = -values.get(this.terms["1"], 0.0)
    start[that.terms[that.play]] = -values.get(this.terms[this.play], 0.0)
    start[that.width] = values.get(this.width) or values.get(that.width) or START_WIDTH_RAD_S
    cand = replace(reading_candidate(that.group), name=candidate_name(that.group))
    cand.terms = {lb: start[p] for lb, p in that.terms.items()}
    cand.widths = {that.play: start[that.width]}
    names = {p: file_name(cand, p) for p in (*that.terms.values(), that.width)}
    return OtherReading(replace(kept, through_values={**values, **start}, file_names=names), cand)


def alternative(kept: KeptCandidate) -> OtherReading | None:
    """The candidate its own fit ranked second (:attr:`~.candidate.Candidate.alternative`) in the kept one's place,
    where it ran through compiled terms and its fit removed at least :data:`.reselection.MIN_CANDIDATE_CUT`; else
    None.

    Parameters
    ----------
    kept : KeptCandidate
        A candidate that entered the model.

    Returns
    -------
    OtherReading or None
        The alternative as a kept candidate (its terms at its own fit's values, its file not written yet).
    """
    c = kept.candidate
    alt = c.alternative if c is not None else None
    fit = alt.fit if alt is not None else None
    if fit is None or fit.through is None or fit.state is None or fit.variance_cut < MIN_CANDIDATE_CUT:
        return None
    own = {p.name for p in fit.through.parameters}
    fitted = fit.state.composition.named(fit.state.result.vector)
    cand = replace(alt, name=candidate_name(alt.group), alternative=None)
    names = {p: file_name(cand, p) for p in fit.file_names if p in own}
    values = {n: float(fitted[n]) for n in own}
    in_place = KeptCandidate(kept.spec, {}, tuple(fit.with_library), fit.through, values, names, cand)
    return OtherReading(in_place, cand, fit.state.composition, ranked_second=True)


def readings_of(kept: KeptCandidate) -> list[OtherReading]:
    """The other readings of a kept candidate to fit with the whole model, in order: its other reading (the terms
    both share from the kept values, then from zero) and its alternative; where the alternative takes its place,
    :func:`drillgym.identify` tries the alternative's own other readings next (they run in the model it was fitted
    in: :attr:`OtherReading.fitted_in`)."""
    out = [other_reading(kept), other_reading(kept, shared_at_zero=True), alternative(kept)]
    return [o for o in out if o is not None]
