"""Motor lag or input delay: decided at the recording's own rate.

A first-order motor lag (time constant tau_m) and a dead time (delay d) of the same size shift the
slow response alike: on the 50 Hz comparison grid of the selection their fits differ by a nat or
less.  They differ in the first tens of milliseconds after each change of the voltage: a delay
shifts the whole response (nothing happens for d seconds, then everything does), a lag starts the
response at once but rounds it.  So the swap decided on the comparison grid (:mod:`.backward`) is
checked again on the recording's own samples (up to :data:`FINE_RATE_HZ`):

* the selected model, and the same model with the other one in its place, have their time constant /
  delay searched again on the fine grid: derivative-free (the response is piecewise constant in a
  delay), the segments' initial speeds refined at every point (speeds refined for one model favour it
  by orders of magnitude of the RSS), the rest of the model held.  When the selection refitted the base
  parameters (with the incumbent in the model), the decision is checked twice and stated as a tie if
  either reverses it: the other one given its own base parameters, refitted with it on the comparison grid
  (:func:`drillgym.diagnosis.lag_delay.own_base`: alone no better a judge, but where it reverses the decision
  the other one is taken, see there), and both with the nominal base parameters;
* the two log-likelihoods are compared (N_eff ln of the RSS ratio, the smaller N_eff of the two fine
  residuals).  The winner by more than :data:`FINE_TIE_NATS` is taken; within that, the two are
  stated as a tie.

Only recordings of at least :data:`MIN_FINE_RATE_HZ` are checked.  At 200 Hz a sample period (5 ms) is a
large part of the lags in question, and the recording does not say whether its voltage was held or
changed linearly between samples (half a sample of shift): on the independent recordings of
``benchmarks/bench_diagnosis_selection.py`` the check at 200 Hz chose the delay for three true motor lags
(by 9-15 nats, also with the other one allowed a sub-sample value), while at 500 Hz and 1 kHz it was right
or a tie on every lag/delay recording of both matrices.  Below that rate the comparison grid's decision
stands, except that it is stated as a tie when the lag or delay is shorter than one comparison period
plus one recording period (:func:`resolvable_lag_delay`).  At any rate, the decision is a tie when the input
is smooth (:func:`input_share_above` below :data:`SMOOTH_INPUT_SHARE` above the upper disc's corner
frequency): on a ramp a lag and a delay shift the response alike, and a decisive fine-grid gap there is the
model's error elsewhere (:func:`drillgym.diagnosis.lag_delay.check_lag_delay`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.signal import welch

from ..errors import InputError
from ..identification.experiment import Experiment, prepare_experiment
from ..identification.fitting import Objective
from ..identification.lane_batch import run_jobs
from ..identification.segmented import SegmentedModel
from .effective import effective_samples
from .effects import get_effect
from .scoring import SEPARATES_LAG_DELAY

__all__ = [
    "FINE_RATE_HZ",
    "FINE_TIE_NATS",
    "LAG_DELAY",
    "SMOOTH_INPUT_SHARE",
    "FineDecision",
    "decide_lag_delay",
    "decide_lag_delay_many",
    "input_share_above",
    "resolvable_lag_delay",
]

#: highest comparison rate (Hz) of the fine check: 1 kHz resolves a 10 ms lag's rounding
FINE_RATE_HZ = 1000.0
#: the two effects the check separates
LAG_DELAY = ("motor_lag", "input_delay")
#: the fine grid must be at least this many times finer than the comparison grid to tell more
MIN_REFINEMENT = 2.0
#: recordings slower than this (Hz) are not checked (see the module docstring)
MIN_FINE_RATE_HZ = 500.0
#: each time constant / delay is searched on [0, max(SEARCH_SPAN x the selected one's value, SEARCH_MIN_S)] (s)
SEARCH_SPAN, SEARCH_MIN_S = 3.0, 0.06
#: points of the coarse grid of that search, then iterations of a bounded scalar search around its best
GRID_POINTS, SEARCH_ITERATIONS = 9, 12
#: a decision at the recording's rate by fewer nats is stated as a tie.  The gap is a Gaussian likelihood
#: ratio with N_eff from the lag-1 correlation; a real rig's friction is not the model's, so it is
#: overconfident.  On the independent recordings of ``bench_diagnosis_selection.py`` (the three fixed
#: matrices and five matrices of random combinations) the wrong decisions had gaps of 6.0, 9.9, 19.2 and 40.0
#: nats; the right ones 0.0-14.4 nats (stated ties) or 54.9 nats and more (most above 100).  Below 50 nats
#: a decision is not trusted (the comparison grid's :data:`.scoring.TIE_NATS`, 3 nats, and 20 nats both let
#: a wrong decision through).
FINE_TIE_NATS = 50.0


def _best_value(obj, comp, vector: np.ndarray, name: str, hi: float) -> tuple[float, np.ndarray]:
    """(value, residual) of the one parameter ``name`` (s) that fits best on [0, hi], the rest of ``vector``
    held: a coarse grid, then a bounded scalar search around its best point.  Derivative-free: the
    simulated response is piecewise constant in a delay (the input is held over integration steps), so a
    finite-difference fit stalls.  The segments' initial speeds are refined at every point (a profile over
    them): speeds refined for one value favour that value by orders of magnitude of the RSS."""
    from scipy.optimize import minimize_scalar

    i = comp.param_index(name)
    model = obj.model
    seen: dict[float, np.ndarray] = {}  # residual per value tried (the best one is not simulated again)

    def residual(x: float) -> np.ndarray:
        if x not in seen:
            v = vector.copy()
            v[i] = x
            model.refine_initial_speeds(v, obj.weights, obj.scales, fresh=True)
            seen[x] = obj.residual_matrix(v[None, :])[0]
        return seen[x]

    def rss(x: float) -> float:
        r = residual(x)
        return float(r @ r)

    grid = np.linspace(0.0, hi, GRID_POINTS)
    values = [rss(g) for g in grid]
    k = int(np.argmin(values))
    step = grid[1] - grid[0]
    res = minimize_scalar(
        rss,
        bounds=(max(0.0, grid[k] - step), min(hi, grid[k] + step)),
        method="bounded",
        options={"xatol": 2e-4, "maxiter": SEARCH_ITERATIONS},
    )
    x = float(res.x) if res.fun <= values[k] else float(grid[k])
    return x, residual(x)


#: an input with less than this share of its variance above the upper disc's corner frequency bu / (2π Ju)
#: is smooth: ramps of the benchmark's recordings have 0.000, steps 0.045-0.061, quasi-random inputs
#: 0.056-0.093, sums of sines 0.18-0.22 (30 s, 1 V ± 3 V, five seeds each)
SMOOTH_INPUT_SHARE = 0.01


def input_share_above(ex: Experiment, f_hz: float) -> float:
    """Share of the recorded input's variance at frequencies above a given one.

    Welch periodogram of the input on its own samples, resampled uniformly at their mean rate.

    Parameters
    ----------
    ex : Experiment
        The recording.
    f_hz : float
        The frequency (Hz).

    Returns
    -------
    float
        The share (1.0 when the input is too short to tell).
    """
    t, u = np.asarray(ex.u_time, dtype=float), np.asarray(ex.u_value, dtype=float)
    if len(t) < 16 or t[-1] <= t[0]:
        return 1.0
    fs = (len(t) - 1) / float(t[-1] - t[0])
    uu = np.interp(t[0] + np.arange(len(t)) / fs, t, u)
    f, p = welch(uu - uu.mean(), fs=fs, nperseg=min(len(uu), int(8 * fs)))
    total = float(p.sum())
    return float(p[f > f_hz].sum() / total) if total > 0 else 0.0


def resolvable_lag_delay(exps: Sequence[Experiment]) -> float:
    """Shortest motor lag or input delay (s) whose kind the comparison grid can tell when the recording is
    too slow for the fine check (:mod:`.timing`): one period of the comparison grid plus one of the
    recording (which does not say whether its voltage was held or ramped between samples).  Shorter, a
    lag and a delay of the same size differ by less than a comparison sample: seen on independent
    recordings at 200 Hz, 17-20 ms delays and lags taken for each other with no tie.

    Parameters
    ----------
    exps : sequence of Experiment
        The recordings.

    Returns
    -------
    float
        The shortest resolvable lag or delay (s), the largest of the recordings'.
    """
    out = 0.0
    for ex in exps:
        ts = ex.recording
        rate = (len(ts.t) - 1) / float(ts.t[-1] - ts.t[0]) if ts is not None and len(ts.t) > 2 else ex.fs
        out = max(out, 1.0 / ex.fs + 1.0 / rate)
    return out


@dataclass
class FineDecision:
    """Outcome of the check at the recording's own rate.

    The gap grows with the recording's length while a rig's own model error does not shrink, so
    :attr:`log_rss_ratio` (the relative difference of the two fits) is reported beside it.

    Attributes
    ----------
    chosen, other : str
        The effect chosen and the other one.
    gap : float
        The score gap (nats; positive favours ``chosen``): n_eff ln(RSS_other / RSS_chosen).
    rate_hz : float
        The fine grid's rate (Hz).
    values : dict of str to float
        Each effect's fitted value there (s).
    doubt : str
        Why a decisive gap is not trusted ("" if it is): a model wrong elsewhere decides nothing.
    n_eff : float
        Effectively independent samples of the residuals compared (NaN: not known).
    nominal_base : dict or None
        The same check with the base parameters at their nominal values when they were refitted
        (``{chosen, score_gap_nats, log_rss_ratio}``; None: not run).
    own_base : dict or None
        The same check with the other one given its own base parameters, refitted with it on the comparison
        grid (None: not run).
    """

    chosen: str
    other: str
    gap: float
    rate_hz: float
    values: dict[str, float]
    #: why a decisive gap is not trusted ("" if it is): a model wrong elsewhere decides nothing
    doubt: str = ""
    #: effectively independent samples of the residuals compared (nan: not known)
    n_eff: float = float("nan")
    #: the same check with the base parameters at their nominal values when they were refitted
    #: ({chosen, score_gap_nats, log_rss_ratio}; None: not run)
    nominal_base: dict | None = None
    #: the same check with the other one given its own base parameters, refitted with it on the comparison
    #: grid, when the base parameters were refitted ({chosen, score_gap_nats, log_rss_ratio}; None: not run)
    own_base: dict | None = None

    @property
    def log_rss_ratio(self) -> float:
        """ln(RSS_other / RSS_chosen): the two fits' relative difference, whatever the recording's length."""
        return self.gap / self.n_eff if self.n_eff > 0 else float("nan")

    def brief(self) -> dict:
        """{chosen, score_gap_nats, log_rss_ratio}: this decision as a check of another one reports it."""
        return {
            "chosen": self.chosen,
            "score_gap_nats": round(self.gap, 2),
            "log_rss_ratio": round(self.log_rss_ratio, 6) if self.n_eff > 0 else None,
        }

    def reversed_by(self, check: FineDecision) -> bool:
        """Whether another decision reverses this one decisively.

        Parameters
        ----------
        check : FineDecision
            The same question asked of other models.

        Returns
        -------
        bool
            Whether it chose the other one by :data:`FINE_TIE_NATS` or more.
        """
        return check.chosen != self.chosen and check.gap >= FINE_TIE_NATS

    @property
    def tie(self) -> bool:
        return abs(self.gap) < FINE_TIE_NATS or bool(self.doubt)

    def to_json(self) -> dict:
        return {
            "chosen": self.chosen,
            "other": self.other,
            "score_gap_nats": round(self.gap, 2),
            "rate_hz": round(self.rate_hz, 1),
            "fitted_s": self.values,
            "tie": self.tie,
            "doubt": self.doubt,
            "n_eff": round(self.n_eff, 1) if self.n_eff > 0 else None,
            "log_rss_ratio": round(self.log_rss_ratio, 6) if self.n_eff > 0 else None,
            "own_base": self.own_base,
            "nominal_base": self.nominal_base,
        }

    def tie_note(self) -> str:
        """The ranking's note on the chosen effect when the two are a tie."""
        v = ", ".join(f"{k} {1e3 * x:.0f} ms" for k, x in self.values.items())
        why = (
            f"score difference {abs(self.gap):.1f} nats, not trusted: {self.doubt}"
            if self.doubt
            else f"score difference {abs(self.gap):.1f} nats"
        )
        return (
            f"indistinguishable from {self.other} at the recording's rate ({self.rate_hz:.0f} Hz; {why}; "
            f"fitted {v}): " + SEPARATES_LAG_DELAY
        )


def fine_rate(ex: Experiment) -> float | None:
    """The rate of the fine grid for an experiment.

    Parameters
    ----------
    ex : Experiment
        The experiment.

    Returns
    -------
    float or None
        Its recording's own rate (Hz, at most :data:`FINE_RATE_HZ`), or None if it has no recording, one
        slower than :data:`MIN_FINE_RATE_HZ`, or one not :data:`MIN_REFINEMENT` times finer than its
        comparison grid.
    """
    ts = ex.recording
    if ts is None or len(ts.t) < 3:
        return None
    rate = min(FINE_RATE_HZ, (len(ts.t) - 1) / float(ts.t[-1] - ts.t[0]))
    return rate if rate >= max(MIN_REFINEMENT * ex.fs, 0.99 * MIN_FINE_RATE_HZ) else None


def fine_experiments(exps: Sequence[Experiment]) -> list[Experiment] | None:
    """The experiments again on their recordings' own rate (:func:`fine_rate`).

    Parameters
    ----------
    exps : sequence of Experiment
        The experiments.

    Returns
    -------
    list of Experiment or None
        The fine experiments, or None if one has no finer data.
    """
    rates = [fine_rate(ex) for ex in exps]
    if not exps or any(r is None for r in rates):
        return None
    return [
        prepare_experiment(ex.recording, ex.config, compare_rate_hz=r, lvdt_lowpass_hz=ex.lvdt_lowpass_hz, name=ex.name)
        for ex, r in zip(exps, rates)
    ]


def decide_lag_delay(
    exps: Sequence[Experiment],
    comp,
    models: Mapping[str, np.ndarray],
    incumbent: str,
    weights: dict,
    segment_s: float | None,
) -> FineDecision | None:
    """Lag or delay, decided on the recordings' own rate.

    Each one's time constant or delay is searched again on the fine grid, the rest of its vector held.

    Parameters
    ----------
    exps : sequence of Experiment
        The recordings.
    comp : Composition
        The models' composition.
    models : mapping of str to numpy.ndarray
        The model vector with the motor lag and the one with the input delay (the other one neutral in each).
    incumbent : str
        The one selected on the comparison grid.
    weights : dict of str to float
        The channels' weights.
    segment_s : float or None
        Multiple-shooting segment length (s).

    Returns
    -------
    FineDecision or None
        The decision, or None when the recordings are not fine enough (:func:`fine_rate`).
    """
    return decide_lag_delay_many(exps, comp, [(models, incumbent)], weights, segment_s)[0]


def decide_lag_delay_many(
    exps: Sequence[Experiment],
    comp,
    questions: Sequence[tuple[Mapping[str, np.ndarray], str]],
    weights: dict,
    segment_s: float | None,
    known: dict | None = None,
) -> list[FineDecision | None]:
    """:func:`decide_lag_delay` for several (models, incumbent) questions on the same recordings, their
    searches run together (threads over the cores: three searches on two cores take the time of two
    rounds, not three).  A search asked twice (the same vector, parameter and range) runs once; ``known``
    (a dict, updated in place) carries searches over from an earlier call.  The decisions are those of
    :func:`decide_lag_delay` asked one by one.

    Parameters
    ----------
    exps : sequence of Experiment
        The recordings.
    comp : Composition
        The models' composition.
    questions : sequence of (mapping of str to numpy.ndarray, str)
        Each question's models (as :func:`decide_lag_delay`) and incumbent.
    weights : dict of str to float
        The channels' weights.
    segment_s : float or None
        Multiple-shooting segment length (s).
    known : dict, optional
        Searches made already, by key; updated in place.

    Returns
    -------
    list of FineDecision or None
        One decision per question.

    Raises
    ------
    InputError
        A question without both models, or with an incumbent that is neither.
    """
    from .segments import place_segment_starts, robust_noise

    for models, incumbent in questions:
        if set(models) != set(LAG_DELAY) or incumbent not in LAG_DELAY:
            raise InputError(f"decide_lag_delay needs the models of {LAG_DELAY} and one of them as incumbent")
    fine = fine_experiments(exps)
    if fine is None:
        return [None] * len(questions)
    conditioned = [robust_noise(ex) for ex in fine]
    scales = {c: min(s[c] for _, s in conditioned) for c in conditioned[0][1]}
    model = SegmentedModel([c[0] for c in conditioned], segment_s, composition=comp, method="rk4")
    if segment_s is not None:
        place_segment_starts(model)
    obj = Objective(model, weights, scales)
    par = {e: get_effect(e).parameters[0].name for e in LAG_DELAY}  # tau_m, delay
    known = {} if known is None else known
    jobs: dict[tuple, tuple[np.ndarray, str, float]] = {}
    keys = []
    for models, incumbent in questions:
        # the range from the incumbent's value only (the other one is neutral, or refitted from that value), so
        # that questions asking the incumbent's model again share its search
        hi = max(SEARCH_SPAN * float(models[incumbent][comp.param_index(par[incumbent])]), SEARCH_MIN_S)
        pair = {}
        for e in LAG_DELAY:
            key = (e, np.asarray(models[e], dtype=float).tobytes(), hi, segment_s)
            pair[e] = key
            if key not in known:
                jobs[key] = (np.asarray(models[e], dtype=float), par[e], hi)
        keys.append(pair)
    if jobs:
        # each search on its own copy of the segmented model (the segments' initial speeds are refined per
        # point), in threads; the kernels release the GIL, so one search's simulation runs while another's
        # Python runs, and the runs they ask for together share a kernel call (lane_batch.run_jobs).  A lane's
        # result does not depend on the batch it runs in
        # (:data:`drillgym.simulator.LANE_BLOCK`), so this gives the values of the searches run one by one
        searches = [partial(_best_value, obj.with_own_speeds(), comp, vec, name, hi) for vec, name, hi in jobs.values()]
        known.update(zip(jobs, run_jobs(searches, 3)))
    out: list[FineDecision | None] = []
    for (_models, a), pair in zip(questions, keys):
        b = LAG_DELAY[1 - LAG_DELAY.index(a)]
        (va, ra), (vb, rb) = known[pair[a]], known[pair[b]]
        ne = min(effective_samples(ra, obj.block_ids), effective_samples(rb, obj.block_ids))
        gap = ne * math.log(max(float(rb @ rb), 1e-300) / max(float(ra @ ra), 1e-300))
        values = {a: va, b: vb}
        if gap < 0:
            out.append(FineDecision(b, a, -gap, float(fine[0].fs), values, n_eff=ne))
        else:
            out.append(FineDecision(a, b, gap, float(fine[0].fs), values, n_eff=ne))
    return out
