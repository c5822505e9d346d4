"""A library effect that a sensor's reading draws as well: a reading tried in its place.

An LVDT whose gain is off by k reads (1 + k) x: the orbit drawn as an ellipse along the LVDTs' axes, which the
library's ``lateral_anisotropy`` (a stiffness that differs in x and y) draws too, and ``lvdt_skew`` nearly.  Below
the lateral resonance the orbit's size hardly depends on the stiffness, so the selection takes the library effect
for the reading (a 4 % gain as dk = 50 N/m), the base refit takes what it cannot, and the residual left (1-2 noise
units) is too small for the sensors' readings to be tried (:data:`.unexplained.EXPLAINED_RATIO`).

Where the selection took such an effect, each reading that draws it is fitted in its place: on the final model
with the effect at its neutral values (:func:`.candidate_fit.fit_candidate`, the base parameters freed as for any
candidate).  The reading replaces the effect when its fit leaves at most :data:`READING_BETTER` of the residual
sum of squares the model with the effect leaves on the sensors' channels (the angles' share is common to both and
would hide the difference), with as many parameters (a scale and an offset against a
stiffness and a damping difference, or one skew): "the y LVDT reads (1 + k) y with k = +0.046, not a stiffness that
differs in x and y (lateral_anisotropy)".  The reading then enters the model as a kept candidate does, and the
library selected again beside it (:mod:`.reselection`) decides whether the library effect was there as well.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .candidate import Candidate
from .candidate_fit import fit_candidate
from .group_terms import write_candidate
from .reading_terms import SENSORS
from .sensor_reading import reading_candidate, with_fitted_terms
from .unexplained import unexplained

__all__ = ["IMITATED", "READING_BETTER", "ReadingVerdict", "reading_in_place"]

#: the library effects a sensor's reading draws as well -> those sensors' candidate groups
IMITATED = {"lateral_anisotropy": ("lvdt_x", "lvdt_y"), "lvdt_skew": ("lvdt_x", "lvdt_y")}
#: a reading replaces the library effect when its fit leaves at most this share of the residual sum of squares
#: the model with the effect leaves (as many parameters each: a clear margin, not a tie broken by noise)
READING_BETTER = 0.8

_LIBRARY_WORDS = {
    "lateral_anisotropy": "a stiffness that differs in x and y (lateral_anisotropy)",
    "lvdt_skew": "LVDTs whose axes are not square (lvdt_skew)",
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


def reading_in_place(
    screening, diagnosis, noise_scales: dict[str, float], candidate_out: str | Path | None = None
) -> ReadingVerdict | None:
    """The sensor's reading that, in a selected library effect's place, leaves clearly less than it.

    Parameters
    ----------
    screening : Screening
        The recordings screened.
    diagnosis : Diagnosis
        The diagnosis (its selection, final model and residual).
    noise_scales : dict of str to float
        The channels' noise.
    candidate_out : str, path or None, optional
        Where the best reading's effect file goes (None: not written).

    Returns
    -------
    ReadingVerdict or None
        The best such reading, fitted (its file written to ``candidate_out``); None when no library effect a
        reading draws was selected, or no reading leaves at most :data:`READING_BETTER` of its residual sum of
        squares.
    """
    comp, un = diagnosis.composition, diagnosis.unexplained
    if comp is None or diagnosis.vector is None or un is None:
        return None
    best: ReadingVerdict | None = None
    for eff in comp.effects:
        if eff.name not in IMITATED or eff.name not in diagnosis.selected:
            continue
        channels = {SENSORS[group].channel for group in IMITATED[eff.name]}
        library = _misfit(un.channels, channels)
        without = _without(screening, diagnosis, eff, noise_scales)
        for group in IMITATED[eff.name]:
            reading = reading_candidate(group)
            reading.fit = fit_candidate(screening, without, reading, noise_scales)
            if reading.fit is None:
                continue
            with_fitted_terms(reading)
            ratio = _misfit(reading.fit.after.channels, channels)
            if ratio**2 <= READING_BETTER * library**2 and (best is None or ratio < best.reading_ratio):
                best = ReadingVerdict(eff.name, reading, library, ratio)
    if best is not None and candidate_out is not None:
        write_candidate(best.reading, candidate_out)
    return best


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
