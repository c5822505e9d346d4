"""The end of one run of the forward selection: backward check, lag or delay, is the base model off?

* **Backward check** (:func:`backward_check`).  With two or more effects accepted, or one with the base
  parameters free, each is removed in turn (the rest and the base parameters refitted to convergence from
  the model with it); an effect whose removal is not significant is dropped.
* **Lag or delay** (:func:`swap_lag_delay`).  When a motor lag or an input delay is selected, the other is
  fitted in its place, both models refitted once more with the segments' initial speeds refined for each
  (speeds refined for the selected one favour it: a 45 s, 200 Hz recording of a delay under base mismatch
  kept a lag without a tie); scores within :data:`.scoring.TIE_NATS` are a tie.  The recording's own rate
  decides again later when it is fine enough (:mod:`.lag_delay`).
* **Is the base model off?** (:func:`decide_base`).  The final effects are refitted with the base
  parameters held at their nominal values; unless the base-freed model fits
  :data:`.scoring.NESTED_RECHECK` times better, that nested model is fitted to convergence (with its own
  segment speeds), and if it fits better than the base-freed one, the freed fit stopped in a worse optimum
  and is continued from the nested one's.  If freeing the base parameters is significant (k = the number of
  base parameters), the base parameters that moved (by at least :data:`.scoring.MOVED_PCT` and three
  standard errors) are reported, with the fit's identifiability warnings.  Otherwise the base model stands
  and the effects keep their values fitted on it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .context import TORQUE_SCALE, base_at_bounds, converged_fit, fit_free
from .effective import effective_samples
from .results import BaseChange, Selection
from .scoring import MOVED_PCT, NESTED_RECHECK, SEPARATES_LAG_DELAY, SIGNIFICANCE, TIE_NATS, score, significant
from .timing import LAG_DELAY

if TYPE_CHECKING:
    from .forward import SearchState

__all__ = ["backward_check", "swap_lag_delay", "decide_base", "scale_warning", "slow_motor_warning"]


def backward_check(state: SearchState) -> None:
    """Drop each selected effect whose removal is not significant (in place on ``state``).

    Parameters
    ----------
    state : SearchState
        The run's state; effects accepted up front get their score here.
    """
    ctx, opts, obj = state.ctx, state.options, state.obj
    if not (len(ctx.selected) >= 2 or (ctx.selected and ctx.base_names) or state.tried_group):
        return
    for name in list(ctx.selected):
        others = [s for s in ctx.selected if s != name]
        # the model without it fitted to convergence as well: nested models compared each at its optimum
        res_full = state.residual
        with obj.model.speeds_kept():
            without = state.converged(ctx.neutralise(ctx.vec, name), state.free_with(others), opts.max_nfev_joint)
            speeds_without = obj.model.speeds_snapshot()
        state.residual = res_full
        full_fit = ctx.fit if ctx.fit is not None else without
        k = len(ctx.effect_parameters([name]))
        chans = state.channels_for(name)
        sc, _ = score(without.residual, full_fit, k, opts.n_eff_ref, chans, state.blocks)
        for stp in state.steps:  # effects accepted up front get their score here
            if stp.effect == name and not stp.score == stp.score:
                stp.score, stp.rss_before, stp.rss_after = sc, without.rss_after, state.rss
        if not significant(
            sc, without.rss_after, state.rss, state.n, without.residual, state.residual, chans, state.units()
        ):
            state.dropped[name] = f"removed by the backward check (score {sc:.1f} once the others are in)"
            ctx.selected.remove(name)
            ctx.vec, state.rss, state.residual = without.vector, without.rss_after, without.residual
            ctx.fit, obj.model.speed_offsets = without, speeds_without


def swap_lag_delay(state: SearchState) -> None:
    """Fit the other of a selected motor lag or input delay in its place; take it if it fits better, and
    state a tie when the two are within :data:`.scoring.TIE_NATS` (in place on ``state``).

    Parameters
    ----------
    state : SearchState
        The run's state.
    """
    ctx = state.ctx
    for a, b in (LAG_DELAY, LAG_DELAY[::-1]):
        if a in ctx.selected and b in ctx.effects and b not in ctx.selected:
            gap, swapped, rss_b = _lag_delay_gap(state, a, b)
            if gap < 0:  # the other one fits better: take it
                ctx.selected[ctx.selected.index(a)] = b
                ctx.vec, ctx.fit = swapped.vector, swapped
                state.rss = state.refine_for(ctx.vec) if state.options.refine else rss_b
                a, b = b, a
            if abs(gap) < TIE_NATS:
                state.ties[a] = (
                    f"indistinguishable from {b} on these data (score difference {abs(gap):.1f} nats): "
                    + SEPARATES_LAG_DELAY
                )
            return


def _lag_delay_gap(state: SearchState, a: str, b: str):
    """(score gap in favour of the selected ``a``, the model with ``b`` in its place, that model's RSS).
    Each model gets the segments' initial speeds refined for it: speeds refined for the selected one favour
    it (by tens of nats on independent recordings)."""
    ctx, opts = state.ctx, state.options
    others = [s for s in ctx.selected if s != a]
    names_b = state.free_with(others + [b])
    swapped = fit_free(ctx, ctx.neutralise(ctx.vec, a), names_b, opts.max_nfev_joint, fresh=[b])
    if not (opts.refine and ctx.fit is not None):
        gap = (
            score(swapped.rss_after, ctx.fit, 0, opts.n_eff_ref, blocks=state.blocks)[0]
            if ctx.fit is not None
            else float("inf")
        )
        return gap, swapped, swapped.rss_after
    rss_b = state.refine_for(swapped.vector)
    again = fit_free(ctx, swapped.vector, names_b, opts.max_nfev_joint)
    if again.rss_after < rss_b:
        swapped, rss_b = again, again.rss_after
    rss_a = state.refine_for(ctx.vec)  # back to the selected model's speeds, and its second pass alike
    again = fit_free(ctx, ctx.vec, state.free_with(ctx.selected), opts.max_nfev_joint)
    if again.rss_after < rss_a:
        ctx.vec, ctx.fit, rss_a, state.residual = again.vector, again, again.rss_after, again.residual
    state.rss = rss_a
    ne = max(effective_samples(state.residual, state.blocks), opts.n_eff_ref)
    return ne * math.log(max(rss_b, 1e-300) / max(rss_a, 1e-300)), swapped, rss_b


#: RMS of a residual in noise units at or below which a model reproduces the recording (no verdict against it)
AT_NOISE = 1.0


def _noise_rms(residual: np.ndarray, units: np.ndarray) -> float:
    """The RMS of a residual in noise units (0 for an empty residual)."""
    r = np.asarray(residual, dtype=float) * units
    return float(np.sqrt(np.mean(r * r))) if r.size else 0.0


def decide_base(state: SearchState) -> Selection:
    """Whether the base model is off, and the run's result (see the module docstring).

    Parameters
    ----------
    state : SearchState
        The run's state after the backward check and the lag/delay swap.

    Returns
    -------
    Selection
        The run's result.
    """
    ctx, opts, obj = state.ctx, state.options, state.obj
    common = dict(
        selected=list(ctx.selected),
        steps=state.steps,
        last_round=state.last_round,
        dropped=state.dropped,
        ties=state.ties,
        rss_nominal=state.rss_nominal,
        n=state.n,
        excluded=state.excluded,
        blocks=state.blocks,
    )
    if not ctx.base_names:
        return Selection(**common, vector=ctx.vec, rss_final=state.rss, fit=ctx.fit)
    eff_names = ctx.effect_parameters(ctx.selected)
    nominal_base = ctx.nominal_base(ctx.vec)
    full = ctx.fit if ctx.fit is not None else state.base_fit
    # the nested model (base held), first with the freed model's segment speeds; where that leaves the freed
    # base less than NESTED_RECHECK times better, fitted to convergence with its own speeds (speeds fitted
    # for the freed base favour it)
    speeds_held = obj.model.speeds_snapshot()
    held = fit_free(ctx, nominal_base, eff_names, opts.max_nfev_joint)
    if opts.refine and held.rss_after < NESTED_RECHECK * full.rss_after:
        with obj.model.speeds_kept():
            held = converged_fit(ctx, nominal_base, eff_names, opts.max_nfev_joint, opts.refine)
            speeds_held = obj.model.speeds_snapshot()
    if eff_names and held.rss_after < full.rss_after:
        # the base-freed fit stopped in a worse optimum than its own nested model reaches (an exact-base
        # recording: base-first from a base fit at +9 %, RSS 6464, against 4645 with the base held): it is
        # continued from the nested model's optimum
        again = state.converged(held.vector, list(ctx.base_names) + eff_names, opts.max_nfev_joint)
        if again.rss_after < full.rss_after:
            ctx.vec, state.rss, ctx.fit, full = again.vector, again.rss_after, again, again
    rss_held = held.rss_after
    base_score, _ = score(rss_held, full, len(ctx.base_names), opts.n_eff_ref, blocks=state.blocks)
    base_off = significant(
        base_score, rss_held, full.rss_after, state.n, held.residual, full.residual, unit=state.units()
    ) or (base_score > SIGNIFICANCE and full.rss_after < 0.5 * rss_held)
    if base_off and _noise_rms(held.residual, state.units()) <= AT_NOISE:
        base_off = False  # the base model already reproduces the recording to its noise: nothing says it is off
    if not base_off:
        obj.model.speed_offsets = speeds_held
        return Selection(
            **common,
            base_score=base_score,
            vector=held.vector,
            rss_final=rss_held,
            fit=held if eff_names else None,
            base_fit=full,
        )
    moved = _moved(ctx, full)
    warn = [w for w in full.warnings if any(n in w for n in ctx.base_names)]
    warn += scale_warning(moved)
    warn += slow_motor_warning(moved, ctx.selected, float(ctx.nominal[ctx.comp.param_index("Ju")]))
    return Selection(
        **common,
        at_bounds=base_at_bounds(ctx, ctx.vec),
        base_off=True,
        base_score=base_score,
        moved=moved,
        base_warnings=warn,
        vector=ctx.vec,
        rss_final=full.rss_after,
        fit=full,
        base_fit=full,
    )


def _moved(ctx, full) -> dict[str, BaseChange]:
    """The freed base parameters that moved by at least MOVED_PCT and three standard errors."""
    moved: dict[str, BaseChange] = {}
    for n in ctx.base_names:
        if ctx.comp.owner(n) is not None:  # a model effect's parameter refitted with the base
            continue
        i = ctx.comp.param_index(n)
        nom, val = float(ctx.nominal[i]), float(ctx.vec[i])
        sd = full.std.get(n, float("nan"))
        pct = 100.0 * (val - nom) / nom if nom else float("nan")
        if nom and abs(pct) >= MOVED_PCT and not (abs(val - nom) < 3 * sd):
            moved[n] = BaseChange(nom, val, pct, sd)
    return moved


def scale_warning(moved: dict[str, BaseChange]) -> list[str]:
    """An identifiability warning when four or more torque and inertia parameters moved alike.

    Torques and inertias all scaled alike is the same model as Ju scaled the other way (Ju is held), and a
    slow motor (lag) looks alike.

    Parameters
    ----------
    moved : dict of str to BaseChange
        The base parameters that moved.

    Returns
    -------
    list of str
        The warning, or nothing.
    """
    ch = [moved[n].change_pct for n in TORQUE_SCALE if n in moved]
    if len(ch) < 4:
        return []
    med = float(np.median(ch))
    alike = [c for c in ch if c * med > 0 and 0.6 < c / med < 1.6]
    if len(alike) < 4:
        return []
    return [
        f"{len(alike)} torque and inertia parameters moved alike (about {med:+.0f} %): the data cannot tell this "
        f"from the upper disc's inertia Ju off by {-med:+.0f} % (Ju is held), and a slow motor or amplifier "
        f"(motor_lag) looks alike; check Ju, or fit with --add-effect motor_lag"
    ]


def slow_motor_warning(moved: dict[str, BaseChange], selected: Sequence[str], ju: float) -> list[str]:
    """A warning naming the motor lag when km and bu moved alike and no lag or delay was selected.

    km and bu moved alike (same sign, within a factor 1.6, each by at least 3 %): the upper disc keeps its
    steady state (km u = bu ω) but its time constant Ju/bu changes, which is what a motor lag of about that
    change looks like on smooth inputs (an independent rig's 33 ms lag on ramps came out as km and bu both
    -10 %, 22 ms on Ju/bu).

    Parameters
    ----------
    moved : dict of str to BaseChange
        The base parameters that moved.
    selected : sequence of str
        The effects selected.
    ju : float
        The upper disc's inertia (kg m²).

    Returns
    -------
    list of str
        The warning, or nothing.
    """
    if any(e in selected for e in LAG_DELAY) or "km" not in moved or "bu" not in moved:
        return []
    a, b = moved["km"].change_pct, moved["bu"].change_pct
    if a * b <= 0 or min(abs(a), abs(b)) < 3.0 or not 1 / 1.6 < a / b < 1.6:
        return []
    bu0, bu1 = moved["bu"].nominal, moved["bu"].fitted
    dtau = ju / bu1 - ju / bu0
    if dtau <= 0:
        return []
    return [
        f"km and bu moved alike ({a:+.1f} %, {b:+.1f} %): the upper disc's steady state is unchanged and it is "
        f"slower by {1e3 * dtau:.0f} ms (Ju/bu), as a motor lag of that size would make it; on smooth inputs (ramps) "
        f"the two look alike: a voltage step recorded at >= 500 Hz decides, or fit with --add-effect motor_lag"
    ]
