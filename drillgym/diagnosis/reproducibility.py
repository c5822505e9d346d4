"""Split-half check of a position-dependent effect: the same in both halves of the recording.

An effect that depends on the lower disc's angle (position friction: the brake level varies once or
twice per revolution) must repeat with the angle.  On a short recording of a slowly turning disc (a few
revolutions) a once-per-revolution harmonic is nearly collinear with any slow variation of the residual,
e.g. a Stribeck curve slightly off, so the selection can accept it where there is none.  Here the final
model is refitted on each half of the recording (the effect's parameters and, if they were freed, the
base parameters); a real effect gives the same parameters in both halves: the two parameter vectors
must point the same way, their cosine similarity above
:data:`MIN_COSINE` (the angle between them below 60°).  A test on the standard errors was tried first and
does not work here: with the base parameters free, each half's errors are so large that a harmonic whose
phase turns by 120° between the halves still passes (a recording of the selection benchmark), while
the full recording's errors are too small for the halves of a real position friction (a second harmonic
absent from the rig comes out +0.008 in one half, -0.005 in the other).  The chi-square of the difference
is reported alongside::

    chi2 = sum_i (p_i,first - p_i,second)^2 / (s_i,first^2 + s_i,second^2)

(standard errors inflated by √(N/N_eff), as in the selection).  The threshold was chosen on two
recordings (a spurious and a real position friction) and then checked on the full and the held-out
matrices of ``benchmarks/bench_diagnosis_selection.py``.

A half in which the effect is not seen cannot confirm it: its fit leaves the parameters where they
started (the full recording's values), and the two vectors then point the same way trivially.  Each half
must show the effect on its own, its Wald statistic above the chi-square's 99 % quantile
(:data:`SHOWN_LEVEL`)::

    W = sum_i (p_i / s_i)^2,   W > chi2_0.99(k)   (k the effect's parameters)

Seen on an independent rig: the lower disc slipped in one excursion of 1.5
revolutions, all in the first half; the second half's standard errors were about 30 against values of
0.04, the cosine 0.995, and a 4-harmonic position friction stood in for the true friction drift.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..identification.experiment import Experiment
from ..identification.fitting import Objective
from .context import SelectionContext, fit_free
from .search_model import SearchModel, selection_model

__all__ = ["split_halves", "HalfAgreement", "halves_agree", "POSITION_NEEDS", "MIN_COSINE", "SHOWN_LEVEL"]

#: an effect whose ``needs`` hold this depends on the lower disc's angle
POSITION_NEEDS = "theta_l"
#: the halves' parameter vectors agree when their cosine similarity exceeds this (60°)
MIN_COSINE = 0.5
#: a half shows the effect when its Wald statistic exceeds the chi-square quantile of this level
SHOWN_LEVEL = 0.99


def split_halves(ex: Experiment) -> tuple[Experiment, Experiment]:
    """The first and the second half (in time) of an experiment.

    The recorded input is kept whole (the model reads it by absolute time), and so is the clock: the second
    half's model starts at the time since the recording's start (a friction drift is 1 + drift t over the
    whole run, not restarted).

    Parameters
    ----------
    ex : Experiment
        The experiment.

    Returns
    -------
    tuple of (Experiment, Experiment)
        The halves (they share the middle sample).
    """
    n = ex.n
    h = n // 2
    origin = float(ex.t[0]) if ex.t_origin is None else ex.t_origin

    def part(sl: slice, tag: str) -> Experiment:
        return replace(
            ex,
            t=ex.t[sl],
            meas={k: v[sl] for k, v in ex.meas.items()},
            rates={k: v[sl] for k, v in ex.rates.items()},
            name=f"{ex.name} ({tag} half)",
            t_origin=origin,
        )

    return part(slice(0, h + 1), "first"), part(slice(h, n), "second")


@dataclass
class HalfAgreement:
    """Outcome of :func:`halves_agree` for one effect."""

    effect: str
    chi2: float
    first: dict[str, float]
    second: dict[str, float]
    first_std: dict[str, float] = field(default_factory=dict)
    second_std: dict[str, float] = field(default_factory=dict)

    def shown(self, half: str) -> bool:
        """Whether a half shows the effect on its own: W = sum (p / s)^2 above the chi-square quantile.

        A parameter with an infinite standard error (the half does not depend on it) adds nothing; with no
        standard error known at all, nothing is judged (True).

        Parameters
        ----------
        half : str
            ``'first'`` or ``'second'``.

        Returns
        -------
        bool
            Whether it shows the effect.
        """
        from scipy.stats import chi2

        values, std = (self.first, self.first_std) if half == "first" else (self.second, self.second_std)
        sds = {p: std.get(p, float("nan")) for p in values}
        if all(math.isnan(sd) for sd in sds.values()):
            return True
        w = sum((values[p] / sd) ** 2 for p, sd in sds.items() if math.isfinite(sd) and sd > 0)
        return w > float(chi2.ppf(SHOWN_LEVEL, len(values)))

    @property
    def cosine(self) -> float:
        """Cosine similarity of the two halves' parameter vectors."""
        a = np.array(list(self.first.values()))
        b = np.array(list(self.second.values()))
        na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
        return float(a @ b / (na * nb)) if na > 0 and nb > 0 else 0.0

    @property
    def shown_in_both(self) -> bool:
        """Each half shows the effect on its own (:meth:`shown`)."""
        return self.shown("first") and self.shown("second")

    @property
    def agree(self) -> bool:
        """Both halves show the effect, and their parameter vectors point the same way."""
        return self.shown_in_both and self.cosine > MIN_COSINE

    def note(self) -> str:
        unseen = [h for h in ("first", "second") if not self.shown(h)]
        if unseen:
            return (
                f"not seen in the {' and '.join(unseen)} half of the recording (its fit leaves the parameters "
                f"undetermined): a position-dependent effect must repeat with the angle; a recording in which "
                f"the lower disc slips through several revolutions in both halves decides"
            )
        vals = ", ".join(f"{p} {self.first[p]:.3g} / {self.second[p]:.3g}" for p in self.first)
        return (
            f"not the same in both halves of the recording ({vals}; cosine {self.cosine:.2f}, chi2 "
            f"{self.chi2:.1f}): "
            f"a position-dependent effect must repeat with the angle; a longer recording (more revolutions) "
            f"decides"
        )


def halves_agree(
    exps: Sequence[Experiment],
    model: SearchModel,
    vector: np.ndarray,
    effect,
    free_base: Sequence[str],
    segment_s: float | None,
    scales: dict[str, float],
    max_nfev: int = 15,
) -> HalfAgreement:
    """Refit an effect's parameters on each half of the recordings and compare them (module docstring).

    Parameters
    ----------
    exps : sequence of Experiment
        The recordings.
    model : SearchModel
        The search model: its composition, channel weights and nominal vector.
    vector : numpy.ndarray
        The model's vector.
    effect : Effect class
        The effect checked.
    free_base : sequence of str
        The base parameters refitted with it.
    segment_s : float or None
        Multiple-shooting segment length (s).
    scales : dict of str to float
        The channels' scales.
    max_nfev : int, optional
        Least-squares evaluations per half.  Default 15.

    Returns
    -------
    HalfAgreement
        The two halves' parameters and their agreement.
    """
    comp, weights, nominal = model.comp, model.obj.weights, model.nominal
    names = [p.name for p in effect.parameters]
    halves = list(zip(*(split_halves(ex) for ex in exps)))  # (first halves, second halves)
    fits = []
    for part in halves:
        halves_model = selection_model(part, segment_s, comp)
        obj = Objective(halves_model, weights, scales)
        halves_model.refine_initial_speeds(vector, obj.weights, obj.scales)
        ctx = SelectionContext(obj, comp, vector.copy(), nominal.copy(), tuple(free_base), {effect.name: effect})
        fits.append(fit_free(ctx, vector, list(free_base) + names, max_nfev))
    a, b = fits
    c2 = 0.0
    for p in names:
        sa, sb = a.std.get(p, float("nan")), b.std.get(p, float("nan"))
        var = sa * sa + sb * sb
        if not (math.isfinite(var) and var > 0):
            continue
        c2 += (a.values[p] - b.values[p]) ** 2 / var
    return HalfAgreement(
        effect.name,
        c2,
        {p: a.values[p] for p in names},
        {p: b.values[p] for p in names},
        {p: a.std.get(p, float("nan")) for p in names},
        {p: b.std.get(p, float("nan")) for p in names},
    )
