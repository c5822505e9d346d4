"""Forward selection with refit: which SET of effects a recording shows, the base parameters re-identified.

Ranking candidates one at a time against the nominal base model fails on real recordings: a second
effect's residual inflates the residual's autocorrelation (nothing passes), and a base model a few
percent off leaves a residual that some effect partly mimics.  One run of :func:`forward_select`:

1. **Base parameters first.**  The base parameters the configuration excites
   (:data:`.context.BASE_FREE`) are fitted first, with any effects accepted up front, within
   :data:`.context.BASE_BOUNDS` of their nominal values, and stay free in every later fit, so mismatch is
   absorbed by the base parameters, never by an effect.  Every fit that changes the model fits the
   segments' initial speeds with it, to convergence (:func:`.context.converged_fit`): an under-converged
   base fit leaves residual that a small effect then takes as evidence.
2. **Rounds.**  Every candidate not yet in the model is screened (its own parameters fitted from the best
   of a spread of starts, :mod:`.starts`, the rest held; with the base freed, also from the nominal base
   parameters: the base refit may have absorbed part of an effect); the ``n_joint`` best are refitted
   jointly with the base parameters and the effects already accepted; the best is accepted when it is
   significant (:mod:`.scoring`), and the rest are re-ranked on the new residual.  When the best is not
   significant, the leading ones are fitted together, then the leader with the partner that fits best
   beside it (an effect can make the fit worse alone and explain nearly everything with another); the
   rounds stop when no group is significant either.
3. **Sensor weights** (``balance``).  With encoders and LVDTs both recorded, each sensor is weighted by
   the model's misfit on it (:func:`.scoring.balance_sensors`), the model refitted and the rounds
   continued, until the weights settle; later search orders keep the final weights.
4. **Backward check, lag or delay, base model decision**: :mod:`.backward`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import FitFailedError
from ..identification.fitting import FitResult, Objective
from .backward import backward_check, decide_base, swap_lag_delay
from .context import SelectionContext, converged_fit, fit_free, in_parallel, screen_fit
from .results import Selection, SelectionStep
from .scoring import balance_sensors, score, significant
from .search_model import SearchModel
from .selection_options import SelectionOptions

__all__ = ["SearchStart", "SearchState", "forward_select"]


@dataclass(frozen=True)
class SearchStart:
    """Where one run of the forward selection starts.

    Attributes
    ----------
    free_base : bool
        Free the search model's base parameters (False: hold them at their nominal values).
    initial : tuple of str
        Effects accepted before the rounds (fitted jointly with the base parameters from ``vector``, then
        subject to the backward check).
    vector : numpy.ndarray or None
        The start of that fit (default: the nominal vector).
    excluded : mapping of str to str
        Candidates left out, and why.
    balance : bool
        Weigh the sensors by the model's misfit when the rounds end, refit and continue while the weights
        change (with base parameters; in place on the objective, so later runs use the final units).
    prior_sigma : float
        > 0: every fit with base parameters is a maximum a posteriori one, with their Gaussian prior of
        this relative width around the nominal vector.
    """

    free_base: bool = True
    initial: tuple[str, ...] = ()
    vector: np.ndarray | None = None
    excluded: Mapping[str, str] = field(default_factory=dict)
    balance: bool = False
    prior_sigma: float = 0.0


@dataclass
class SearchState:
    """The state of one run of the forward selection as its model grows.

    Attributes
    ----------
    ctx : SelectionContext
        The fit state (current vector, effects selected, fit).
    options : SelectionOptions
        The search's settings.
    nominal : numpy.ndarray
        The nominal vector.
    n : int
        Residual samples.
    blocks : numpy.ndarray
        The independent block of each residual sample.
    noise_scales : dict of str to float
        The channels' noise scales before any sensor weighting.
    residual : numpy.ndarray
        The current model's residual.
    rss : float
        Its sum of squares.
    rss_nominal : float
        The nominal model's.
    balance : bool
        Whether the sensors are weighted by their misfit.
    base_fit : FitResult or None
        The first base fit.
    steps : list of SelectionStep
        The accepted steps.
    last_round : dict of str to SelectionStep
        The last round's scores.
    excluded, dropped, ties : dict of str to str
        Candidates whose fits failed, effects removed, ties stated, each with why.
    tried_group : bool
        Whether a group of candidates was tried together.
    """

    ctx: SelectionContext
    options: SelectionOptions
    nominal: np.ndarray
    n: int
    blocks: np.ndarray
    noise_scales: dict[str, float]
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rss: float = 0.0
    rss_nominal: float = 0.0
    balance: bool = False
    base_fit: FitResult | None = None
    steps: list[SelectionStep] = field(default_factory=list)
    last_round: dict[str, SelectionStep] = field(default_factory=dict)
    excluded: dict[str, str] = field(default_factory=dict)
    dropped: dict[str, str] = field(default_factory=dict)
    ties: dict[str, str] = field(default_factory=dict)
    tried_group: bool = False

    @property
    def obj(self) -> Objective:
        """The objective fitted."""
        return self.ctx.obj

    def free_with(self, effects: Sequence[str]) -> list[str]:
        """The parameters a fit of some effects frees.

        Parameters
        ----------
        effects : sequence of str
            Candidate names.

        Returns
        -------
        list of str
            The freed base parameters, then the effects' parameters.
        """
        return list(self.ctx.base_names) + self.ctx.effect_parameters(effects)

    def refine_for(self, vec: np.ndarray) -> float:
        """The segments' speeds refined for a model (with ``refine``); its residual becomes the current one.

        Parameters
        ----------
        vec : numpy.ndarray
            The model's vector.

        Returns
        -------
        float
            Its sum of squares.
        """
        obj = self.obj
        if self.options.refine:
            obj.model.refine_initial_speeds(vec, obj.weights, obj.scales, fresh=True)
        r = obj.residual_matrix(vec[None, :])[0]
        self.residual = r
        return float(r @ r)

    def converged(self, vec: np.ndarray, names: Sequence[str], max_nfev: int) -> FitResult:
        """A fit to convergence (:func:`.context.converged_fit`), its residual becoming the current one.

        Parameters
        ----------
        vec : numpy.ndarray
            The start.
        names : sequence of str
            The parameters fitted.
        max_nfev : int
            Least-squares evaluations per fit.

        Returns
        -------
        FitResult
            The fit.
        """
        best = converged_fit(self.ctx, vec, names, max_nfev, self.options.refine)
        self.residual = best.residual
        return best

    def take(self, fit: FitResult) -> None:
        """Make a fit the current model.

        Parameters
        ----------
        fit : FitResult
            The fit.
        """
        self.ctx.vec, self.rss, self.ctx.fit = fit.vector, fit.rss_after, fit

    def channels_for(self, name: str) -> np.ndarray | None:
        """The channel of each residual entry, for scoring a candidate per channel.

        A measurement effect changes only its own channels, so its likelihood ratio is the per-channel one
        (:func:`.scoring.score`); dynamic effects change every channel and are scored on the pooled residual.

        Parameters
        ----------
        name : str
            The candidate.

        Returns
        -------
        numpy.ndarray or None
            The channel ids for a measurement effect, else None.
        """
        return self.obj.channel_ids if self.ctx.is_measurement(name) else None

    def units(self) -> np.ndarray:
        """Per residual entry: noise units per unit of the (misfit-weighted) residual."""
        obj = self.obj
        f = np.array([obj.scales[c] / self.noise_scales[c] for c in obj.channels])
        return f[obj.channel_ids]


def forward_select(model: SearchModel, options: SelectionOptions, start: SearchStart | None = None) -> Selection:
    """One run of the selection on the search model (see the module docstring).

    Parameters
    ----------
    model : SearchModel
        The search model: objective, composition, nominal vector (candidates neutral), candidates and
        the base parameters that may be freed.
    options : SelectionOptions
        How hard to search.
    start : SearchStart, optional
        Where the run starts (default: the base parameters freed, no effect).

    Returns
    -------
    Selection
        The effects selected, the base model decision and the final model.
    """
    state = _begin(model, options, start or SearchStart())
    for weighting in range(3):  # the rounds, then again while the sensors' weights settle
        _grow(state, first_pass=weighting == 0)
        if not _settle_weights(state):
            break
    backward_check(state)
    if state.obj.scales != state.noise_scales:  # the nominal model's residual in the final units ("before")
        state.rss_nominal = state.refine_for(state.nominal)
        state.rss = state.refine_for(state.ctx.vec)
    swap_lag_delay(state)
    return decide_base(state)


def _begin(model: SearchModel, options: SelectionOptions, start: SearchStart) -> SearchState:
    """The state before the rounds: the nominal model's residual, the effects accepted up front, the base
    parameters fitted first (with them)."""
    excluded = dict(start.excluded)
    vec0, obj = model.nominal, model.obj
    ctx = SelectionContext(
        obj,
        model.comp,
        vec0.copy(),
        vec0.copy(),
        tuple(model.base_names) if start.free_base else (),
        {c.name: c for c in model.candidates if c.name not in excluded},
        prior_sigma=start.prior_sigma,
    )
    n = obj.residual_matrix(vec0[None, :]).shape[1]
    state = SearchState(
        ctx, options, vec0, n, obj.block_ids, dict(obj.scales), balance=start.balance, excluded=excluded
    )
    state.rss_nominal = state.refine_for(vec0)
    state.rss = state.rss_nominal
    ctx.selected = [n_ for n_ in start.initial if n_ in ctx.effects]
    v_init = vec0 if start.vector is None else start.vector
    for name in ctx.selected:
        state.steps.append(SelectionStep(name, float("nan"), state.rss_nominal, state.rss_nominal, {}, {}, True, 0.0))
    if ctx.base_names:
        state.base_fit = state.converged(v_init, state.free_with(ctx.selected), options.max_nfev_base)
        state.take(state.base_fit)
    return state


def _settle_weights(state: SearchState) -> bool:
    """Each sensor's channels weighted by the current model's misfit, and the model refitted with them
    (twice at most); True if the weights changed."""
    changed = False
    ctx = state.ctx
    for _ in range(2):
        if not (state.balance and ctx.base_names and balance_sensors(state.obj, state.residual, state.noise_scales)):
            break
        changed = True
        state.take(state.converged(ctx.vec, state.free_with(ctx.selected), max(4, state.options.max_nfev_base // 2)))
    return changed


def _grow(state: SearchState, first_pass: bool) -> None:
    """Rounds of screening and acceptance until no candidate or group is significant, or the model holds
    ``max_effects`` effects."""
    ctx, opts = state.ctx, state.options
    while len(ctx.selected) < opts.max_effects:
        screen = _screen(state, first_pass)
        if not screen:
            return
        order = sorted(screen, key=lambda n: screen[n].rss_after)
        round_, joint = _score_round(state, screen, order)
        best = max(joint or round_, key=lambda n: round_[n].score)
        if not round_[best].significant:
            # the joint refits go to the best by pooled RSS; a measurement effect, judged on its own
            # channel, can be significant without being among them (an LVDT skew changes y only)
            passing = [n for n in round_ if round_[n].significant]
            if passing:
                best = max(passing, key=lambda n: round_[n].score)
        state.last_round = round_
        if not round_[best].significant:
            if state.tried_group or opts.max_effects - len(ctx.selected) < 2 or not _enter_group(state, screen, order):
                return
            continue
        ctx.selected.append(best)
        state.steps.append(round_[best])
        # more passes with speeds refined for the extended model
        state.take(
            state.converged(
                joint[best].vector if best in joint else screen[best].vector,
                state.free_with(ctx.selected),
                opts.max_nfev_joint,
            )
        )


def _screen(state: SearchState, first_pass: bool) -> dict[str, FitResult]:
    """Every candidate not in the model screened, the best of its fits by RSS; failed fits excluded.

    The base refit may have absorbed part of an effect (a motor lag looks like a slower upper disc): in the
    first pass with the base parameters freed, every candidate is also screened from the nominal base
    parameters with the accepted effects (once the weights changed, the model has its base refit)."""
    ctx = state.ctx
    starts = [ctx.vec]
    if ctx.base_names and first_pass:
        starts.append(ctx.nominal_base(ctx.vec))
    tasks = [(name, v) for name in ctx.effects if name not in ctx.selected for v in starts]
    fits = in_parallel(
        [
            lambda name=name, v=v: screen_fit(ctx, v, name, state.options.max_nfev_screen, state.options.refine)
            for name, v in tasks
        ]
    )
    screen: dict[str, FitResult] = {}
    for (name, _), r_ in zip(tasks, fits):
        if isinstance(r_, FitFailedError):
            state.excluded[name] = f"fit failed: {r_}"
            continue
        if name not in screen or r_.rss_after < screen[name].rss_after:
            screen[name] = r_
    return screen


def _score_round(
    state: SearchState, screen: dict[str, FitResult], order: Sequence[str]
) -> tuple[dict[str, SelectionStep], dict[str, FitResult]]:
    """Each screened candidate's step (its score against the current model), the ``n_joint`` best refitted
    jointly with the base parameters and the accepted effects; returns the steps and the fits that scored
    best for those refitted."""
    ctx, opts = state.ctx, state.options
    free_now = state.free_with(ctx.selected)
    joint_fits = dict(
        zip(
            order[: opts.n_joint],
            in_parallel(
                [
                    lambda name=name: fit_free(
                        ctx, screen[name].vector, free_now + ctx.effect_parameters([name]), opts.max_nfev_joint
                    )
                    for name in order[: opts.n_joint]
                ]
            ),
        )
    )
    round_: dict[str, SelectionStep] = {}
    joint: dict[str, FitResult] = {}
    for name in order:
        res = screen[name]
        k = len(res.names)
        if res.rss_after > state.rss:  # the effect at its neutral values: nothing explained
            res.rss_after, res.residual = state.rss, state.residual.copy()
        chans = state.channels_for(name)
        sc, ne = score(state.residual, res, k, opts.n_eff_ref, chans, state.blocks)
        jr = joint_fits.get(name)
        if jr is not None and not isinstance(jr, FitFailedError):
            # the joint refit or the screen's fit, whichever scores higher: the joint refit lowers the pooled
            # RSS, but a measurement effect is scored per channel, and the base parameters refitted with it
            # can trade the torsional channels for its own (an independent rig's 2.5° LVDT skew: its screen
            # +133 nats; the joint refit, RSS 8916 -> 8864, moved the base so that θl and θu lost more nats
            # than y and x gained, -22 nats)
            sj, nj = (
                score(state.residual, jr, k, opts.n_eff_ref, chans, state.blocks)
                if jr.rss_after <= state.rss
                else (-math.inf, ne)
            )
            if sj > sc:
                res, sc, ne = jr, sj, nj
            joint[name] = res
        eff_vals = {
            p: res.values.get(p, float(res.vector[ctx.comp.param_index(p)])) for p in ctx.effect_parameters([name])
        }
        eff_std = {p: res.std.get(p, float("nan")) for p in eff_vals}
        sig = significant(sc, state.rss, res.rss_after, state.n, state.residual, res.residual, chans, state.units())
        round_[name] = SelectionStep(name, sc, state.rss, res.rss_after, eff_vals, eff_std, sig, ne)
    return round_, joint


def _enter_group(state: SearchState, screen: dict[str, FitResult], order: Sequence[str]) -> bool:
    """Masking: several effects at once leave a residual no single one explains enough of (each one's
    residual is dominated by the others').  The leading candidates are fitted together; if the group is
    significant it enters whole, and the backward check removes those that do not count.  Else the leading
    candidate with the one partner that fits best beside it: an effect can make the fit worse alone and
    explain nearly all with another (a 37 ms input delay without the string damping that came with it).
    Returns whether a group entered."""
    ctx, opts = state.ctx, state.options
    free_now = state.free_with(ctx.selected)
    for group, gv in _masked_groups(state, screen, order):
        try:
            gr = fit_free(ctx, gv, free_now + ctx.effect_parameters(group), opts.max_nfev_joint)
        except FitFailedError:
            continue
        kg = len(ctx.effect_parameters(group))
        sc, ne = score(state.rss, gr, kg, opts.n_eff_ref, blocks=state.blocks)
        if significant(sc, state.rss, gr.rss_after, state.n, state.residual, gr.residual, unit=state.units()):
            break
    else:
        return False
    for n in group:
        vals = {p: float(gr.vector[ctx.comp.param_index(p)]) for p in ctx.effect_parameters([n])}
        state.steps.append(
            SelectionStep(
                n,
                sc,
                state.rss,
                gr.rss_after,
                vals,
                {p: gr.std.get(p, float("nan")) for p in vals},
                True,
                ne,
                note=f"entered with {', '.join(g for g in group if g != n)}",
            )
        )
    ctx.selected += group
    state.tried_group = True
    state.take(state.converged(gr.vector, state.free_with(ctx.selected), opts.max_nfev_joint))
    return True


def _masked_groups(
    state: SearchState, screen: dict[str, FitResult], order: Sequence[str]
) -> Iterator[tuple[list[str], np.ndarray]]:
    """Groups of candidates to fit together when none is significant alone, each with its start vector:
    the ``n_group`` best by their screens (those that explained anything), then the best screened
    candidate with the partner whose screen beside it (its parameters fitted from their best start, the
    leader's held at its screened values) leaves the smallest RSS."""
    ctx, opts = state.ctx, state.options
    room = opts.max_effects - len(ctx.selected)
    group = [n for n in order if screen[n].rss_after < state.rss][: min(opts.n_group, room)]

    def start(members: Sequence[str], src: dict[str, np.ndarray]) -> np.ndarray:
        gv = ctx.vec.copy()
        for n in members:
            for p in ctx.effect_parameters([n]):
                gv[ctx.comp.param_index(p)] = src[n][ctx.comp.param_index(p)]
        return gv

    if len(group) >= 2:
        yield group, start(group, {n: screen[n].vector for n in group})
    lead = order[0]
    base = start([lead], {lead: screen[lead].vector})
    best: tuple[float, str, np.ndarray] | None = None
    for other in ctx.effects:
        if other in ctx.selected or other == lead:
            continue
        try:
            r = fit_free(ctx, ctx.best_start(base, other), ctx.effect_parameters([other]), opts.max_nfev_screen)
        except FitFailedError:
            continue
        if best is None or r.rss_after < best[0]:
            best = (r.rss_after, other, r.vector)
    if best is not None and set(group) != {lead, best[1]}:
        yield [lead, best[1]], best[2]
