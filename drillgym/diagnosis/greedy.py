"""Greedy forward selection of regression terms: what discovery's groups (:mod:`.discovery`,
:mod:`.lateral_discovery`) enter their terms by."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np

__all__ = ["MAX_TERMS", "MIN_GAIN", "MAX_CANCEL", "greedy_terms", "with_quadratures"]

MAX_TERMS = 3
MIN_GAIN = 0.03  # share of the residual variance a further term must explain
MAX_CANCEL = 2.0  # a term may contribute at most this many times the residual's size


def greedy_terms(cols: list[np.ndarray], yr: np.ndarray, tss: float) -> tuple[list[int], float]:
    """Terms entered one at a time (at most ``MAX_TERMS``), each the one that explains most beside those in;
    returns their indices and the share of ``yr``'s variance they explain."""
    chosen: list[int] = []
    share = 0.0
    for _ in range(MAX_TERMS):
        trial = None
        for j in range(len(cols)):
            if j in chosen or not np.any(np.abs(cols[j]) > 1e-12 * (np.abs(cols[j]).max() + 1e-300)):
                continue
            X = np.column_stack([cols[i] for i in chosen + [j]])
            c, *_ = np.linalg.lstsq(X, yr, rcond=None)
            # terms that cancel each other (each contributing more than the residual itself, as collinear
            # terms do) fit the noise, not an effect: such a set is not a candidate
            if np.any(np.abs(c) * np.linalg.norm(X, axis=0) > MAX_CANCEL * math.sqrt(tss)):
                continue
            sh = 1.0 - float(np.sum((yr - X @ c) ** 2)) / tss
            if trial is None or sh > trial[1]:
                trial = (j, sh, c)
        # a further term must explain MIN_GAIN of the residual, or a third of what the terms so far leave
        if trial is None or trial[1] - share < min(MIN_GAIN, (1.0 - share) / 3.0):
            break
        chosen.append(trial[0])
        share = trial[1]
    return chosen, share


_HARMONIC = re.compile(r"\b(cos|sin) ")


def with_quadratures(chosen: list[int], labels: Sequence[str]) -> list[int]:
    """The chosen terms and, for each harmonic among them (a label with ``cos kθ`` or ``sin kθ``), its quadrature
    (the same label with ``sin kθ`` or ``cos kθ``) when it is a term too: a periodic torque has an amplitude and a
    phase.  On the residual torque (twice differentiated, smoothed) the smaller component of a harmonic can fall
    below :data:`MIN_GAIN` and be left out, while in the simulated angles it leaves several times the noise (an
    independent rig's cogging −T sin(6θu + φ) proposed as cos 6θu alone left 4.4 noise units on θu); the
    candidate's own fit then sets both components.

    Parameters
    ----------
    chosen : list of int
        Indices of the terms entered (:func:`greedy_terms`).
    labels : sequence of str
        Every term's label.

    Returns
    -------
    list of int
        ``chosen``, then the quadratures it lacks.
    """
    index = {label: i for i, label in enumerate(labels)}
    out = list(chosen)
    for j in chosen:
        other = _HARMONIC.sub(lambda m: "sin " if m.group(1) == "cos" else "cos ", labels[j])
        k = index.get(other)
        if other != labels[j] and k is not None and k not in out:
            out.append(k)
    return out
