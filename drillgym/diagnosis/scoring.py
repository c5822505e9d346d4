"""How the selection counts evidence: the score of a larger model, the significance rules, sensor weights.

A larger model (one more effect, or the base parameters freed) is scored against a smaller one by

    score = N_eff ln(RSS_small / RSS_large) − k ln N_eff

with k the added parameters and ``N_eff = Σ_b max(1, n_b (1 − ρ)/(1 + ρ))`` over the independent blocks b
(each multiple-shooting segment of each channel, :mod:`.effective`), ρ the lag-1 autocorrelation of the
*larger* model's residual: the residual that remains when the effect is in, not the one the effect
removes, measures how correlated the unexplained part is.  It is significant when the score exceeds
:data:`SIGNIFICANCE`, it removes at least :data:`MIN_REDUCTION` of the residual RMS, and it explains more
than the noise (:func:`noise_floor`).  A *measurement* effect (an LVDT's offset or skew) changes only its
own channels, so it is scored per channel and may pass the reduction rule in one channel: pooled, a small
torsional model error drowns a 2° skew that only the y reading shows.
"""

from __future__ import annotations

import math

import numpy as np

from ..identification.fitting import FitResult, Objective
from .effective import effective_samples

__all__ = [
    "SIGNIFICANCE",
    "MIN_REDUCTION",
    "MIN_EXPLAINED",
    "TIE_NATS",
    "SEPARATES_LAG_DELAY",
    "MOVED_PCT",
    "NESTED_RECHECK",
    "SENSORS",
    "score",
    "significant",
    "noise_floor",
    "balance_sensors",
]

SIGNIFICANCE = 15.0  # nats
MIN_REDUCTION = 0.2  # fraction of the residual RMS an accepted effect must remove
MIN_EXPLAINED = 1.0  # noise units²
#: a motor lag and an input delay whose models' scores differ by less (nats) on the comparison grid are a tie
TIE_NATS = 3.0
#: what a stated lag/delay tie recommends
SEPARATES_LAG_DELAY = (
    "a voltage step recorded at 1 kHz or faster separates them (a delay shifts the whole "
    "response, a lag rounds its start)"
)
MOVED_PCT = 1.0  # % change below which a base parameter is not reported as moved
#: the base model decision refits the nested model (base held) to convergence with its own segment speeds
#: when its quick fit (the freed model's speeds) is less than this many times worse than the freed model.
#: Converging lowers the quick fit's RSS 5.7 times on an exact-base recording (26387 to 4645, base-freed
#: 6464: the base stands) and 1.2 times where the base is off (1.46e8 to 1.21e8, freed 6470); a base 10^4
#: times better freed is off whatever the speeds
NESTED_RECHECK = 100.0
#: channels read by one kind of sensor: they share one misfit level (:func:`balance_sensors`)
SENSORS = {"encoders": ("theta_u", "theta_l", "alpha"), "LVDTs": ("x", "y", "r")}


def score(
    rss_small: float | np.ndarray,
    fit_big: FitResult,
    k: int,
    n_eff_ref: float = 0.0,
    channels: np.ndarray | None = None,
    blocks: np.ndarray | None = None,
) -> tuple[float, float]:
    """The score of a larger model's fit against a smaller model's RSS.

    With the smaller model's residual *vector* and ``channels``, each channel has its own noise variance
    and correlation: the log-likelihood ratio is the sum over channels of N_eff,c ln(RSS_c small /
    RSS_c large), and N_eff the sum of the channels'.  A pooled variance lets a large residual in one
    channel (a slightly wrong torsional model) drown an effect that acts on another alone (an LVDT's skew
    changes only y).

    Parameters
    ----------
    rss_small : float or numpy.ndarray
        The smaller model's RSS, or its residual vector.
    fit_big : FitResult
        The larger model's fit.
    k : int
        The parameters the larger model adds.
    n_eff_ref : float, optional
        A lower bound of N_eff.  Default 0.
    channels : numpy.ndarray, optional
        The channel of each residual entry (:attr:`Objective.channel_ids`): score per channel.
    blocks : numpy.ndarray, optional
        The independent block of each residual entry (:func:`.effective.effective_samples`).

    Returns
    -------
    tuple of (float, float)
        The score (nats) and N_eff (the larger model's own residual's, or ``n_eff_ref`` if larger).
    """
    r1 = fit_big.residual
    if channels is None or np.ndim(rss_small) == 0 or r1 is None or len(r1) != len(channels):
        rss0 = float(rss_small) if np.ndim(rss_small) == 0 else float(np.dot(rss_small, rss_small))
        ne = max(effective_samples(r1, blocks), n_eff_ref)
        rss1 = max(fit_big.rss_after, 1e-300)
        return ne * math.log(max(rss0, 1e-300) / rss1) - k * math.log(ne), ne
    r0 = np.asarray(rss_small, dtype=float)
    total, ne_sum = 0.0, 0.0
    for c in np.unique(channels):
        m = channels == c
        a, b = r0[m], r1[m]
        ne_c = effective_samples(b, None if blocks is None or len(blocks) != len(r1) else blocks[m])
        total += ne_c * math.log(max(float(a @ a), 1e-300) / max(float(b @ b), 1e-300))
        ne_sum += ne_c
    ne = max(ne_sum, n_eff_ref)
    return total - k * math.log(ne), ne


def significant(
    sc: float,
    rss0: float,
    rss1: float,
    n: int,
    r0: np.ndarray | None = None,
    r1: np.ndarray | None = None,
    channels: np.ndarray | None = None,
    unit: np.ndarray | None = None,
) -> bool:
    """Whether a larger model counts: its score above :data:`SIGNIFICANCE`, and the residual RMS cut by
    :data:`MIN_REDUCTION` by more than the noise floor, over all channels or (``channels`` given) in one.

    Parameters
    ----------
    sc : float
        The score (nats).
    rss0, rss1 : float
        RSS of the smaller and the larger model.
    n : int
        Residual samples.
    r0, r1 : numpy.ndarray, optional
        Their residual vectors.
    channels : numpy.ndarray, optional
        The channel of each residual entry: the reduction rule may pass in one channel.
    unit : numpy.ndarray, optional
        Per residual entry, the noise units of one unit of the residual (sensors weighted by their misfit,
        :func:`balance_sensors`): the noise floor is in noise units, the cut in the fit's units.

    Returns
    -------
    bool
        Whether it is significant.
    """
    if not sc > SIGNIFICANCE:
        return False
    have = r0 is not None and r1 is not None and len(r0) == len(r1)
    u = unit if have and unit is not None and len(unit) == len(r0) else None

    def power(r: np.ndarray, m: np.ndarray | slice) -> float:
        return float(np.mean(r[m] ** 2)) if u is None else float(np.mean((r[m] * u[m]) ** 2))

    def above_noise(m: np.ndarray | slice) -> bool:
        left = power(r1, m)
        return power(r0, m) - left > noise_floor(left)

    rm0, rm1 = math.sqrt(rss0 / n), math.sqrt(rss1 / n)
    pooled = above_noise(slice(None)) if have else rm0**2 - rm1**2 > noise_floor(rm1**2)
    if rm1 < (1 - MIN_REDUCTION) * rm0 and pooled:
        return True
    if not have or channels is None or len(r0) != len(channels):
        return False
    for c in np.unique(channels):
        m = channels == c
        q0, q1 = float(np.mean(r0[m] ** 2)), float(np.mean(r1[m] ** 2))
        if math.sqrt(q1) < (1 - MIN_REDUCTION) * math.sqrt(q0) and above_noise(m):
            return True
    return False


def noise_floor(left: float) -> float:
    """Residual variance (noise units²) an effect must explain, given the variance ``left`` that remains.

    :data:`MIN_EXPLAINED`, or ``left`` when that is smaller.  The noise unit is a prior (an encoder count
    / √12, 10 µm on an LVDT, :func:`~drillgym.diagnosis.segments.robust_noise`); a model that leaves less
    than one unit shows the sensors are finer than that, and what it leaves bounds their noise from above.
    With a fixed floor of one unit an effect could never be accepted there: a coupled recording's motor lag
    (RMS 0.86 -> 0.48 units, 92 nats) would be refused.

    Parameters
    ----------
    left : float
        The variance left with the effect (noise units²).

    Returns
    -------
    float
        The floor (noise units²).
    """
    return min(MIN_EXPLAINED, max(left, 0.0))


def balance_sensors(
    obj: Objective, residual: np.ndarray, noise_scales: dict[str, float], tol: float = 0.25
) -> dict[str, float]:
    """Weigh each sensor by its own misfit (in place, on ``obj.scales``).

    The residual scale of every channel of a sensor (:data:`SENSORS`) becomes its noise scale times that
    sensor's RMS misfit in noise units, at least 1; ``obj.scales`` changes when a sensor's scale changes by
    more than ``tol``.

    Parameters
    ----------
    obj : Objective
        The objective whose scales are set.
    residual : numpy.ndarray
        The current model's residual, in ``obj``'s layout and units.
    noise_scales : dict of str to float
        Each channel's noise scale.
    tol : float, optional
        Relative change below which nothing changes.  Default 0.25.

    Returns
    -------
    dict of str to float
        Sensor -> its new factor when the scales changed, else {} (one sensor, or no change beyond ``tol``).

    Notes
    -----
    The noise-normalised residual assumes the model errs by noise alone.  A real model errs systematically,
    and unequally per sensor: the friction law's stick phases leave the encoders at several noise units while
    the LVDTs fit to the noise.  Pooled, the encoders then own the fit: the lateral parameters move to fit
    the angles, and what only the LVDTs show (a 2° skew) drowns.  One unknown variance per sensor (maximum
    likelihood) gives every sensor the weight of its own fit; the forward selection calls this again after
    each refit (iteratively reweighted least squares), so a misfit a missing effect caused falls once the
    effect is in.
    """
    present = {name: [c for c in chans if c in obj.channels] for name, chans in SENSORS.items()}
    present = {k: v for k, v in present.items() if v}
    if len(present) < 2:
        return {}
    factors: dict[str, float] = {}
    for name, chans in present.items():
        now = obj.scales[chans[0]] / noise_scales[chans[0]]
        e = residual[np.isin(obj.channel_ids, [obj.channels.index(c) for c in chans])]
        misfit = now * float(np.sqrt(np.mean(e**2))) if e.size else 1.0
        factors[name] = max(1.0, misfit)
    changed = any(
        abs(math.log(f * noise_scales[present[n][0]] / obj.scales[present[n][0]])) > math.log1p(tol)
        for n, f in factors.items()
    )
    if not changed:
        return {}
    for name, f in factors.items():
        for c in SENSORS[name]:
            if c in obj.scales:
                obj.scales[c] = noise_scales[c] * f
    return factors
