"""A candidate effect outside the library, found in the residual torques (:mod:`.discovery`), or a sensor's
reading (:mod:`.sensor_reading`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .reading_terms import SENSORS, reading_words

__all__ = ["Candidate"]


_WHERE = {
    "lower_friction": "lower-disc slip friction +=",
    "upper_friction": "upper-disc slip friction +=",
    "string": "string torque (added to kθ α) +=",
    "lower_force": "torque on the lower disc +=",
    "upper_force": "torque on the upper disc +=",
    "motor_voltage": "voltage at the motor = u",
    "lateral_force": "force on the lower disc's centre (FX, FY), fixed frame +=",
    **{g: f"{s.what[4:]} reading = {s.symbol}" for g, s in SENSORS.items()},
}
#: the unit of a group's coefficients (N m when not listed; a reading's: its own unit per unit of the term)
_UNIT = {"motor_voltage": "V", "lateral_force": "N", **{g: s.unit for g, s in SENSORS.items()}}


@dataclass
class Candidate:
    """A candidate effect found in the residual torques, or a sensor's reading (:mod:`.sensor_reading`).

    Attributes
    ----------
    group : str
        Where it acts: ``lower_friction``, ``upper_friction``, ``string``, ``lower_force``, ``upper_force``,
        ``motor_voltage`` (the voltage the motor sees), ``lateral_force`` (a force on the lower disc's centre,
        :mod:`.lateral_discovery`), or a sensor's reading (:data:`.reading_terms.SENSORS`:
        ``motor_encoder``, ``lower_encoder``, ``lvdt_x``, ``lvdt_y``).
    terms : dict of str to float
        Term label -> coefficient (N m per unit of the term; V for ``motor_voltage``; N for ``lateral_force``; a
        reading's unit, rad or m, per unit of the term: the scale error k is rad/rad or m/m).
    codes : dict of str to str
        Term label -> its Python expression in the effect file.
    at_rest : dict of str to float
        Term label -> its value at zero speed approached from above.
    explained : float
        Share of the residual torque's variance it explains (a reading: share of the unexplained variance its fit
        removes).
    n_samples : int
        Samples regressed.
    name : str
        The effect's name in its file.
    effect_file : str or None
        ``path.py:NAME`` of the file written, if any.
    rest : dict of str to float
        Other groups' best shares, and those of the library effects acting on a disc it acts on
        (:func:`.library_columns.library_view`).
    reach : dict of str to float
        Term label -> the coefficient that would make the term alone as large as the residual torque
        (N m per unit): the file's bounds cover it too.
    widths : dict of str to float
        Term label -> the width scanned for it (a dead zone's u0 in V; the encoder's lead speed in rad/s), fitted
        as a parameter of the file (named ``U0`` in the term's code).
    fit : any
        The candidate's own fit on the diagnosis' recordings (:class:`.candidate_fit.CandidateFit`), or None.
    alternative : Candidate or None
        The motor side's best candidate when this one acts elsewhere (its fit decides which is reported).
    beside : tuple of str
        A library effect acting only on a disc this candidate does not act on, which explains that disc's residual
        (:func:`.library_columns.library_view`): freed in this candidate's freer fit (:mod:`.candidate_fit`) where
        the selection did not take it (two effects at once, on two discs).
    through_lag : float or None
        A motor-side candidate regressed on the voltage after a first-order lag of this time constant (s): the
        residual is explained best with the library's ``motor_lag`` ahead of the terms, and the candidate's fit
        fits that lag with them.  None: on the model's own voltage at the motor.
    constant_force : tuple of float or None
        A lateral candidate regressed beside the constant forces an LVDT offset of the model reads as: the
        constant force (FX, FY) in N the regression gives beside its terms, which the offset takes (x0 += FX / k)
        when the candidate enters.  None: no offset in the model.
    notes : tuple of str
        How some of its terms are written where the recording cannot tell their form (the file's docstring says
        it), e.g. ``|u|`` written as ``u`` on a command that never reverses (:func:`.discovery_terms.odd_form`).
    """

    group: str
    terms: dict[str, float]
    codes: dict[str, str]
    at_rest: dict[str, float]
    explained: float
    n_samples: int
    name: str = ""
    effect_file: str | None = None
    rest: dict[str, float] = field(default_factory=dict)
    reach: dict[str, float] = field(default_factory=dict)
    widths: dict[str, float] = field(default_factory=dict)
    fit: Any = None
    alternative: Any = None
    beside: tuple[str, ...] = ()
    through_lag: float | None = None
    constant_force: tuple[float, float] | None = None
    notes: tuple[str, ...] = ()

    @property
    def dof(self) -> int:
        """Number of terms (the effect's parameters)."""
        return len(self.terms)

    def expression(self) -> str:
        """The candidate as one line: where it acts and its terms with their coefficients (N m, V or rad)."""
        parts = " ".join(f"{c:+.4g}·{n}" if n != "1" else f"{c:+.4g}" for n, c in self.terms.items())
        widths = "".join(f", w = {w:.3g} rad/s" for w in self.widths.values()) if self.is_reading else ""
        return f"{_WHERE[self.group]} {parts}{widths}  [{self.unit}]"

    @property
    def unit(self) -> str:
        """The unit of its coefficients: N m, V (``motor_voltage``), rad or m (a reading)."""
        return _UNIT.get(self.group, "N m")

    @property
    def is_lateral_force(self) -> bool:
        """Whether it is a force on the lower disc's centre (:mod:`.lateral_discovery`)."""
        return self.group == "lateral_force"

    @property
    def is_reading(self) -> bool:
        """Whether it is a sensor's reading (:mod:`.sensor_reading`), not a term of the residual torques."""
        return self.group in SENSORS

    def reading(self) -> str | None:
        """What a reading candidate says about its sensor in words (:func:`.reading_terms.reading_words`), or
        None for a candidate of the residual torques."""
        return reading_words(self.group, self.terms, self.widths) if self.is_reading else None

    def found_line(self) -> str:
        """How the candidate was found and what it is, as the command line's first line on it."""
        if self.is_reading:
            what = SENSORS[self.group].what
            how = f"what {what} reads, by its own fit: {self.explained:.0%} of the unexplained variance"
            return f"candidate outside the library ({how}): {self.reading()} — {self.expression()}"
        how = f"{self.explained:.0%} of the residual {'lateral force' if self.group == 'lateral_force' else 'torque'}"
        beside = (
            f"; the library's {' and '.join(self.beside)} explains the other disc's, freed in its fit"
            if self.beside
            else ""
        )
        return f"candidate outside the library ({how}{beside}): {self.expression()}"

    def to_json(self) -> dict:
        """The candidate as a JSON-ready dict."""
        return {
            "name": self.name,
            "expression": self.expression(),
            "dof": self.dof,
            "explained": round(self.explained, 4),
            "effect_file": self.effect_file,
            "group": self.group,
            "reading": self.reading(),
            "terms": self.terms,
            "widths": self.widths,
            "through_lag_s": self.through_lag,
            "beside": list(self.beside),
            "fit": self.fit.to_json() if self.fit is not None else None,
            "alternative": None
            if self.alternative is None
            else {
                "expression": self.alternative.expression(),
                "group": self.alternative.group,
                "explained": round(self.alternative.explained, 4),
                "fit": self.alternative.fit.to_json() if self.alternative.fit is not None else None,
            },
        }
