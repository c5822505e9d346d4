"""A library effect that a sensor's reading draws as well: a reading tried in its place.

An LVDT whose gain is off by k reads (1 + k) x: the orbit drawn as an ellipse along the LVDTs' axes, which the
library's ``lateral_anisotropy`` (a stiffness that differs in x and y) draws too, and ``lvdt_skew`` nearly.  Below
the lateral resonance the orbit's size hardly depends on the stiffness, so the selection takes the library effect
for the reading (a 4 % gain as dk = 50 N/m), the base refit takes what it cannot, and the residual left (1-2 noise
units) is too small for the sensors' readings to be tried (:data:`.unexplained.EXPLAINED_RATIO`).  The encoders
have theirs: a lower encoder whose zero is off the motor's turns the angle the unbalance is drawn at, the orbit's
phase against the lower disc's angle, which ``lvdt_skew`` draws nearly; an encoder whose counts per revolution are
off reads a twist that grows with the angle turned, a torque that grows along the run as ``friction_drift``'s.
:data:`IMITATED` lists them.

Where the selection took such an effect, each reading that draws it is fitted in its place: on the final model
with the effect at its neutral values (:func:`.candidate_fit.fit_candidate`, the base parameters freed as for any
candidate).  The reading replaces the effect when its fit leaves at most :data:`READING_BETTER` of the residual
sum of squares the model with the effect leaves on the channels of the sensors that draw it (the other channels'
share is common to both and would hide the difference), with about as many parameters (a scale and an offset
against a stiffness and a damping difference, or one skew): "the y LVDT reads (1 + k) y with k = +0.046, not a
stiffness that differs in x and y (lateral_anisotropy)".  It is tried whatever discovery found, and taken in the
place of discovery's candidate where it leaves less over all channels.  The reading then enters the model as a
kept candidate does, and the library selected again beside it (:mod:`.reselection`) decides whether the library
effect was there as well.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .candidate import Candidate
from .candidate_fit import fit_candidate
from .reading_terms import SENSORS
from .sensor_reading import reading_candidate, with_fitted_terms
from .unexplained import unexplained

__all__ = ["IMITATED", "READING_BETTER", "ReadingVerdict", "reading_in_place"]

#: the library effects a sensor's reading draws as well -> the readings that draw it: the sensor's candidate group
#: and the terms it draws it with (``scale``, ``offset``: about as many parameters as the effect, no more)
IMITATED: dict[str, tuple[tuple[str, tuple[str, ...]], ...]] = {
    "lateral_anisotropy": (("lvdt_x", ("scale", "offset")), ("lvdt_y", ("scale", "offset"))),
    "lvdt_skew": (("lvdt_x", ("scale", "offset")), ("lvdt_y", ("scale", "offset")), ("lower_encoder", ("offset",))),
    "friction_drift": (("lower_encoder", ("scale", "offset")), ("motor_encoder", ("scale", "offset"))),
}
#: a reading replaces the library effect when its fit leaves at most this share of the residual sum of squares
#: the model with the effect leaves (as many parameters each: a clear margin, not a tie broken by noise)
READING_BETTER = 0.8

_LIBRARY_WORDS = {
    "lateral_anisotropy": "a stiffness that differs in x and y (lateral_anisotropy)",
    "lvdt_skew": "LVDTs whose axes are not square (lvdt_skew)",
    "friction_drift": "a friction level that drifts along the run (friction_drift)",
}


@dataclass(frozen=True)
class ReadingVerdict:
    """A sensor's reading that explains what a selected library effect explained, and more.

    Attributes
    ----------
    library : str
        The library effect the selection took.
    reading : Candidate
        The reading, fitted in its place (its fit holds the values).
    library_ratio, reading_ratio : float
        The residual RMS over the sensors' channels (an LVDT reading's: x and y) the model leaves with the library
        effect and with the reading in its place (noise units).
    """

    library: str
    reading: Candidate
    library_ratio: float
    reading_ratio: float

    def line(self) -> str:
        """The verdict in words, one line."""
        return (
            f"{self.reading.reading()}, rather than {_LIBRARY_WORDS[self.library]}: with the reading in its "
            f"place the model leaves {self.reading_ratio:.3g} times the noise on the sensors' channels, with "
            f"{self.library} {self.library_ratio:.3g}; the library is selected again beside the reading"
        )


def reading_in_place(screening, diagnosis, noise_scales: dict[str, float]) -> ReadingVerdict | None:
    """The sensor's reading that, in a selected library effect's place, leaves clearly less than it.

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis (its selection, final model and residual).
    noise_scales : dict of str to float
        The channels' noise.

    Returns
    -------
    ReadingVerdict or None
        The best such reading, fitted (its file not written: the caller writes it where it takes the reading);
        None when no library effect a reading draws was selected, or no reading leaves at most
        :data:`READING_BETTER` of its residual sum of squares.
    """
    comp, un = diagnosis.composition, diagnosis.unexplained
    if comp is None or diagnosis.vector is None or un is None:
        return None
    best: ReadingVerdict | None = None
    for eff in comp.effects:
        if eff.name not in IMITATED or eff.name not in diagnosis.selected:
            continue
        channels = {SENSORS[group].channel for group, _ in IMITATED[eff.name]}
        library = _misfit(un.channels, channels)
        without = _without(screening, diagnosis, eff, noise_scales)
        for group, roles in IMITATED[eff.name]:
            reading = _reading(group, roles)
            reading.fit = fit_candidate(screening, without, reading, noise_scales)
            if reading.fit is None:
                continue
            with_fitted_terms(reading)
            ratio = _misfit(reading.fit.after.channels, channels)
            if ratio**2 <= READING_BETTER * library**2 and (best is None or ratio < best.reading_ratio):
                best = ReadingVerdict(eff.name, reading, library, ratio)
    return best


def _reading(group: str, roles: tuple[str, ...]) -> Candidate:
    """A sensor's reading at its start with only the terms of ``roles`` (``scale``: the true quantity read,
    ``offset``: the constant)."""
    sensor = SENSORS[group]
    labels = {{"scale": sensor.symbol, "offset": "1"}[role] for role in roles}
    cand = reading_candidate(group)
    keep = [lb for lb in cand.terms if lb in labels]
    return replace(
        cand,
        terms={lb: cand.terms[lb] for lb in keep},
        at_rest={lb: cand.at_rest[lb] for lb in keep},
        widths={lb: w for lb, w in cand.widths.items() if lb in labels},
    )


def _misfit(ratios: dict[str, float], channels: set[str]) -> float:
    """The RMS over ``channels`` of their residual-to-noise ratios."""
    vals = [ratios[c] for c in channels if c in ratios]
    return float(np.sqrt(np.mean(np.square(vals)))) if vals else 0.0


def _without(screening, diagnosis, effect, noise_scales: dict[str, float]):
    """The diagnosis' final model with ``effect`` at its neutral values, and the residual it leaves."""
    comp = diagnosis.composition
    vector = np.array(diagnosis.vector, dtype=float)
    for name, value in (effect.neutral_values() or {}).items():
        vector[comp.param_index(name)] = value
    return replace(diagnosis, vector=vector, unexplained=unexplained(screening.model.obj, vector, noise_scales))
