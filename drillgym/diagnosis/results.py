"""What a diagnosis produces: typed results, each with ``to_json()``.

* :class:`SelectionStep` — one effect accepted by the forward selection (or scored in its last round);
* :class:`BaseChange` — a base parameter that moved when it was re-identified;
* :class:`Selection` — one run of the forward selection: the effects selected, the base model decision,
  the fitted vector;
* :class:`EffectScore` — one effect's evidence as the diagnosis reports it;
* :class:`Candidate` — an effect outside the library, found in the residual torques;
* :class:`Diagnosis` — the whole answer: the set of effects, the ranking, the base parameters that moved,
  the candidate effect, warnings and advice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..configurations import Configuration
from ..effects import Composition
from ..identification.fitting import FitResult
from ..params import RigParams
from .candidate import Candidate
from .effects import label_effects
from .unexplained import Unexplained

__all__ = ["SelectionStep", "BaseChange", "Selection", "EffectScore", "Candidate", "Diagnosis"]


@dataclass
class SelectionStep:
    """One effect accepted by the forward selection, or scored in its last round.

    Attributes
    ----------
    effect : str
        The effect's name.
    score : float
        Its score (nats): N_eff ln(RSS before / RSS after) − k ln N_eff; NaN until scored.
    rss_before, rss_after : float
        Residual sum of squares of the model without and with it (residual units²).
    values, std : dict of str to float
        Its fitted parameters and their standard errors.
    significant : bool
        Whether the score and the residual it removes pass the selection's rules.
    n_eff : float
        Effectively independent residual samples the score counts.
    note : str
        What else to know (e.g. the effects it entered with).
    """

    effect: str
    score: float
    rss_before: float
    rss_after: float
    values: dict[str, float]
    std: dict[str, float]
    significant: bool
    n_eff: float
    note: str = ""

    def to_json(self) -> dict:
        """The step as a JSON-ready dict."""
        return {
            "effect": self.effect,
            "score": self.score,
            "rss_before": self.rss_before,
            "rss_after": self.rss_after,
            "values": self.values,
            "std": self.std,
            "significant": self.significant,
            "n_eff": self.n_eff,
            "note": self.note,
        }


@dataclass
class BaseChange:
    """A base parameter that moved when it was re-identified.

    Attributes
    ----------
    nominal, fitted : float
        The parameter's nominal and re-identified values (its own unit).
    change_pct : float
        (fitted − nominal) / nominal, in percent.
    std : float
        The fitted value's standard error (its own unit; NaN if unknown).
    """

    nominal: float
    fitted: float
    change_pct: float
    std: float

    def to_json(self) -> dict:
        """``{nominal, fitted, change_pct, std}``."""
        return {"nominal": self.nominal, "fitted": self.fitted, "change_pct": self.change_pct, "std": self.std}


@dataclass
class Selection:
    """One run of the forward selection (:func:`drillgym.diagnosis.forward.forward_select`).

    Attributes
    ----------
    selected : list of str
        The effects selected, in the order accepted.
    steps : list of SelectionStep
        The accepted steps (effects accepted up front get their score from the backward check).
    last_round : dict of str to SelectionStep
        The last round's screens of the effects not selected.
    dropped : dict of str to str
        Effects removed after being accepted, and why.
    ties : dict of str to str
        Selected effects the data cannot tell from another one, and the note that says so.
    at_bounds : list of str
        Base parameters at a bound of their range (empty when the base model stands).
    base_off : bool
        Whether freeing the base parameters is significant.
    base_score : float
        The score (nats) of freeing the base parameters.
    moved : dict of str to BaseChange
        The base parameters that moved beyond their uncertainty.
    base_warnings : list of str
        Identifiability warnings about the base parameters.
    vector : numpy.ndarray
        The final model's parameter vector (search composition).
    rss_nominal, rss_final : float
        Residual sum of squares of the nominal model and of the final one.
    n : int
        Residual samples.
    fit : FitResult or None
        The final model's fit.
    excluded : dict of str to str
        Candidates whose fits failed, and why.
    base_fit : FitResult or None
        The fit with the base parameters freed.
    blocks : numpy.ndarray or None
        The independent block of each residual sample.
    """

    selected: list[str] = field(default_factory=list)
    steps: list[SelectionStep] = field(default_factory=list)
    last_round: dict[str, SelectionStep] = field(default_factory=dict)
    dropped: dict[str, str] = field(default_factory=dict)
    ties: dict[str, str] = field(default_factory=dict)
    at_bounds: list[str] = field(default_factory=list)
    base_off: bool = False
    base_score: float = 0.0
    moved: dict[str, BaseChange] = field(default_factory=dict)
    base_warnings: list[str] = field(default_factory=list)
    vector: np.ndarray | None = None
    rss_nominal: float = 0.0
    rss_final: float = 0.0
    n: int = 0
    fit: FitResult | None = None
    excluded: dict[str, str] = field(default_factory=dict)
    base_fit: FitResult | None = None
    blocks: np.ndarray | None = None

    def labelled(self) -> list[str]:
        """The selected effects, then ``bound:NAME`` for each base parameter at a bound: how a search
        order is recorded in :attr:`Diagnosis.paths`."""
        return list(self.selected) + [f"bound:{n}" for n in self.at_bounds]

    def to_json(self) -> dict:
        """The selection's decisions as a JSON-ready dict (the vector and fits left out)."""
        return {
            "selected": list(self.selected),
            "steps": [s.to_json() for s in self.steps],
            "dropped": self.dropped,
            "ties": self.ties,
            "at_bounds": self.at_bounds,
            "base_off": self.base_off,
            "base_score": self.base_score,
            "moved": {k: v.to_json() for k, v in self.moved.items()},
            "base_warnings": self.base_warnings,
            "rss_nominal": self.rss_nominal,
            "rss_final": self.rss_final,
            "n": self.n,
            "excluded": self.excluded,
        }


@dataclass
class EffectScore:
    """One effect's evidence.

    Attributes
    ----------
    effect : str
        The effect's name.
    score : float
        Its score (nats).
    rmse_before, rmse_after : float
        Residual RMS of the model without and with it (noise units).
    values, std : dict of str to float
        Its fitted parameters and their standard errors.
    channel_rms_after : dict of str to float
        Residual RMS per channel with it (noise units; empty when not computed).
    signature : str
        What the effect leaves in the residual when it is missing.
    significant : bool
        Whether it counts as found.
    note : str
        A tie or doubt about it ("" if none).
    """

    effect: str
    score: float
    rmse_before: float
    rmse_after: float
    values: dict[str, float]
    std: dict[str, float]
    channel_rms_after: dict[str, float]
    signature: str
    significant: bool
    note: str = ""

    @property
    def reduction(self) -> float:
        """Fraction of the residual RMS removed."""
        return 1.0 - self.rmse_after / self.rmse_before if self.rmse_before > 0 else 0.0

    def to_json(self) -> dict:
        """The score as a JSON-ready dict."""
        return {
            "effect": self.effect,
            "score": round(self.score, 3),
            "rmse_before": self.rmse_before,
            "rmse_after": self.rmse_after,
            "reduction": round(self.reduction, 4),
            "significant": self.significant,
            "values": self.values,
            "std": self.std,
            "note": self.note,
        }


@dataclass(frozen=True)
class Diagnosis:
    """The diagnosis of a recording.

    The ranking lists the selected effects first, in the order accepted, then the rest by their last score.

    Attributes
    ----------
    ranking : list of EffectScore
        Every effect tried.
    config : Configuration
        The recording's configuration.
    rmse_before : float
        Residual RMS of the model diagnosed (noise units, or misfit-weighted units: :attr:`sensor_misfit`).
    channel_rms_before : dict of str to float
        The same per channel.
    n_eff : float
        Effectively independent residual samples of the model diagnosed.
    segment_s : float or None
        Multiple-shooting segment length (s); None: one free run.
    skipped : dict of str to str
        Candidates not tried or removed, and why.
    base_refit : dict of str to float
        The re-identified base parameters when the base model is off.
    model : str
        The label of the model diagnosed.
    selected : list of str
        The effects found.
    base_parameters : dict of str to BaseChange
        The base parameters that moved.
    base_off : bool
        Whether the base model is off.
    base_score : float
        The score (nats) of freeing the base parameters.
    warnings : list of str
        What to be careful about.
    rmse_after : float or None
        Residual RMS of the final model.
    candidate : Candidate or None
        An effect outside the library (discovery).
    composition : Composition or None
        The search model's composition.
    vector : numpy.ndarray or None
        The final model's parameter vector.
    params : RigParams or None
        The final model's base parameters.
    advice : list of str
        Experiments that would show more, when nothing outside the library explains the residual.
    nominal_vector : numpy.ndarray or None
        The final model's vector with the nominal base parameters.
    paths : dict of str to list of str
        What each search order selected.
    lag_delay : dict or None
        The lag/delay decision at the recording's rate (:meth:`.timing.FineDecision.to_json`).
    sensor_misfit : dict of str to float
        Sensor -> the model's misfit on it (noise units), by which its channels were rescaled.
    at_bounds : list of str
        Base parameters the final model left at a bound of their range.
    input_order : InputOrder or None
        The model's two Input effects fitted in both orders (:mod:`.input_order`; None: not two).
    unexplained : Unexplained or None
        The final model's residual against the measurement noise, where it lives and what it depends on
        (None: not measured).  "The base model stands" is said only when it is at the noise.
    reselection : Diagnosis or None
        The diagnosis run again on the model that holds a kept candidate (:mod:`.reselection`; None: no
        candidate kept).
    detectability : Detectability or None
        What the recording's input can show at all: each effect and re-identified base parameter's change of
        the prediction, the pairs of effects it shows alike, the experiment that would show the rest
        (:mod:`.detectability`; None: not measured).
    """

    ranking: list[EffectScore]
    config: Configuration
    rmse_before: float
    channel_rms_before: dict[str, float]
    n_eff: float
    segment_s: float | None
    skipped: dict[str, str] = field(default_factory=dict)
    base_refit: dict[str, float] = field(default_factory=dict)
    model: str = "base"
    selected: list[str] = field(default_factory=list)
    base_parameters: dict[str, BaseChange] = field(default_factory=dict)
    base_off: bool = False
    base_score: float = 0.0
    warnings: list[str] = field(default_factory=list)
    rmse_after: float | None = None
    candidate: Any = None
    composition: Composition | None = None
    vector: np.ndarray | None = None
    params: RigParams | None = None
    advice: list[str] = field(default_factory=list)
    nominal_vector: np.ndarray | None = None
    paths: dict[str, list[str]] = field(default_factory=dict)
    lag_delay: dict | None = None
    sensor_misfit: dict[str, float] = field(default_factory=dict)
    unexplained: Unexplained | None = None
    input_order: Any = None
    at_bounds: list[str] = field(default_factory=list)
    reselection: Diagnosis | None = None
    detectability: Any = None

    @property
    def best(self) -> EffectScore | None:
        """The first effect of the ranking, or None."""
        return self.ranking[0] if self.ranking else None

    def significant(self) -> list[EffectScore]:
        """The effects that count as found."""
        return [s for s in self.ranking if s.significant]

    def effect_values(self) -> dict[str, float]:
        """The selected effects' fitted parameters by name."""
        return {k: v for s in self.ranking if s.effect in self.selected for k, v in s.values.items()}

    def in_turn(self) -> list[Diagnosis]:
        """This diagnosis, then each one run again with a kept candidate in the model (:attr:`reselection`, again
        with the next candidate kept there), in turn."""
        out = [self]
        while out[-1].reselection is not None:
            out.append(out[-1].reselection)
        return out

    def final(self) -> Diagnosis:
        """The last diagnosis of :meth:`in_turn`: the model with every kept candidate (itself when none was kept)."""
        return self.in_turn()[-1]

    def selected_model(self) -> tuple[RigParams, list[dict], dict[str, float]]:
        """The model the diagnosis selected: its base parameters, effect records and base standard errors.

        Returns
        -------
        RigParams
            The final base parameters (re-identified ones included).
        list of dict
            One record per effect of the model diagnosed and of the selection, with its fitted values and
            (finite) standard errors: the signal path's effects first, command side first, then the others
            in the search model's order, so composing the records' specs gives the same signal path.
        dict of str to float
            Standard errors of the base parameters that moved (their units).
        """
        from ..effects import Composition
        from .refit import effect_records

        if self.composition is None or self.vector is None or self.params is None:
            raise ValueError("the diagnosis holds no final model (a ranking alone selects nothing)")
        keep = {*label_effects(self.model), *self.selected}
        path = self.composition.signal_path(among=keep)
        rest = [e.name for e in self.composition.effects if e.name in keep and e.name not in path]
        by_name = {e.name: e for e in self.composition.effects}
        sub = Composition(tuple(by_name[n] for n in path + rest))
        values = self.composition.named(self.vector)
        std = {k: v for s in self.ranking if s.effect in keep for k, v in s.std.items()}
        records = effect_records(sub, values, std=std)
        base_std = {k: v.std for k, v in self.base_parameters.items() if math.isfinite(v.std)}
        return self.params, records, base_std

    def to_json(self) -> dict:
        """The diagnosis as a JSON-ready dict (what ``drillgym diagnose --json`` prints)."""
        cand = self.candidate.to_json() if self.candidate is not None else None
        return {
            "selected": list(self.selected),
            "ranking": [{**s.to_json(), "fitted": s.values} for s in self.ranking],
            "base_parameters": {k: v.to_json() for k, v in self.base_parameters.items()},
            "base_model_off": self.base_off,
            "base_score": round(self.base_score, 3),
            "candidate": cand,
            "warnings": self.warnings,
            "advice": self.advice,
            "configuration": self.config.label,
            "rmse_before": self.rmse_before,
            "rmse_after": self.rmse_after,
            "channel_rms_before": self.channel_rms_before,
            "n_eff": self.n_eff,
            "segment_s": self.segment_s,
            "skipped": self.skipped,
            "base_refit": self.base_refit,
            "model": self.model,
            "search_paths": self.paths,
            "lag_delay": self.lag_delay,
            "sensor_misfit": self.sensor_misfit,
            "signal_path": self._signal_path(),
            "unexplained": self.unexplained.to_json() if self.unexplained is not None else None,
            "input_order": self.input_order.to_json() if self.input_order is not None else None,
            "reselection": self.reselection.to_json() if self.reselection is not None else None,
            "detectability": self.detectability.to_json() if self.detectability is not None else None,
        }

    def _signal_path(self) -> list[str]:
        """The Delay and Input effects of the base model and the selection, command side first."""
        if self.composition is None:
            return []
        return self.composition.signal_path(among=[*label_effects(self.model), *self.selected])

    def text(self) -> str:
        """The diagnosis as the command line prints it."""
        lines = self.unexplained.lines() if self.unexplained is not None else []
        lines.append(self._header())
        if self.sensor_misfit:
            lines.append(
                "each sensor weighted by the model's misfit on it (one misfit-weighted unit): "
                + ", ".join(f"{k} {v:.3g} noise units" for k, v in self.sensor_misfit.items())
            )
        lines += self._base_lines()
        lines += self._ranking_lines()
        if self.lag_delay and not self.lag_delay["tie"]:
            ld = self.lag_delay
            lines.append(
                f"lag or delay, at the recording's rate ({ld['rate_hz']:.0f} Hz): {ld['chosen']} preferred to "
                f"{ld['other']} by {ld['score_gap_nats']:.1f} nats"
            )
        if self.input_order is not None:
            lines.append(self.input_order.line())
        for w in self.warnings:
            lines.append(f"warning: {w}")
        for k, why in self.skipped.items():
            lines.append(f"skipped {k}: {why}")
        if self.detectability is not None:  # only what this recording cannot show (a pair the fine check decided: not)
            ld = self.lag_delay
            decided = [frozenset((ld["chosen"], ld["other"]))] if ld and not ld["tie"] else []
            lines += self.detectability.lines(decided, said=self.skipped)
        if self.advice:
            rest = "the rest of the residual" if self.at_noise else "the residual left unexplained (first lines)"
            lines.append(f"nothing outside the library explains {rest}; experiments that would show more:")
            lines += [f"  - {a_}" for a_ in self.advice]
        return "\n".join(lines)

    def candidate_lines(self) -> list[str]:
        """The candidate found and its fit, the library selected again beside it, then the next candidate found on
        that model's residual, in turn (empty: no candidate)."""
        c = self.candidate
        if c is None:
            return []
        out = [c.found_line()] + ([c.fit.line()] if c.fit is not None else []) + self.reselection_lines()
        return out + (self.reselection.candidate_lines() if self.reselection is not None else [])

    def reselection_lines(self) -> list[str]:
        """The library selected again with the kept candidate in the model, in words (empty: none kept)."""
        r = self.reselection
        if r is None:
            return []
        found = ", ".join(r.selected) or "no library effect"
        out = [f"with the candidate in the model ({r.model}, refitted with the base), the library selected again: "]
        out[0] += found
        # what the recording cannot show was said once, above
        out += ["  " + line for line in replace(r, detectability=None).text().splitlines()]
        return out

    def _header(self) -> str:
        after = f"; after {self.rmse_after:.3g}" if self.rmse_after is not None else ""
        return (
            f"diagnosis of the model {self.model!r} ({self.config.label}; multiple shooting, segments of "
            f"{self.segment_s if self.segment_s else 'whole record'} s; residual RMS "
            f"{self.rmse_before:.3g} {'misfit-weighted' if self.sensor_misfit else 'noise'} units{after}; "
            + ", ".join(f"{c} {v:.3g}" for c, v in self.channel_rms_before.items())
            + ")"
        )

    def _base_lines(self) -> list[str]:
        if self.base_off:
            if not self.base_parameters:
                return ["the base model is off, but no single base parameter moved beyond its uncertainty"]
            return [
                "the base model is off; re-identified base parameters that moved: "
                + ", ".join(
                    f"{k} {v.nominal:.5g} -> {v.fitted:.5g} ({v.change_pct:+.1f} %"
                    + (f" ± {100 * v.std / abs(v.nominal):.1f} %" if not math.isnan(v.std) else "")
                    + ")"
                    for k, v in self.base_parameters.items()
                )
            ]
        if self.base_parameters == {} and self.base_score:
            if self.at_noise:
                return ["base parameters: no significant change (the nominal base model stands)"]
            return [
                "base parameters: no significant change, but the model does not stand: its residual stays above "
                "the noise (first lines)"
            ]
        return []

    @property
    def at_noise(self) -> bool:
        """Whether the final residual is at the measurement noise (:attr:`Unexplained.explained`); False when
        it was not measured: nothing is said to stand unmeasured."""
        return self.unexplained is not None and self.unexplained.explained

    def _ranking_lines(self) -> list[str]:
        lines = [f"{'rank':<5}{'effect':<20}{'score':>10}{'rms after':>11}{'cut':>7}  fitted values"]
        for i, s in enumerate(self.ranking, 1):
            vals = ", ".join(
                f"{k}={v:.4g}" + (f"±{s.std[k]:.2g}" if s.std.get(k) == s.std.get(k) and k in s.std else "")
                for k, v in s.values.items()
            )
            mark = "*" if s.significant else " "
            lines.append(f"{i:<4}{mark}{s.effect:<20}{s.score:>10.1f}{s.rmse_after:>11.3g}{s.reduction:>7.0%}  {vals}")
        rest = [r for r in self.ranking if not r.significant]
        if rest and self.rmse_after and abs(rest[0].rmse_before - self.rmse_after) > 0.05 * self.rmse_after:
            lines.append(
                f"(rows without *: each fitted to the last model the selection tried, residual RMS "
                f"{rest[0].rmse_before:.3g}, not to the final one; 'cut' is relative to that model)"
            )
        if self.selected:
            lines.append("effects found: " + ", ".join(self.selected))
            for s in self.ranking:
                if s.effect in self.selected:
                    lines.append(f"  {s.effect}: {s.signature}")
                    if s.note:
                        lines.append(f"  note: {s.effect} is {s.note}")
        else:
            lines.append("no effect of the library explains a significant part of the residual")
        return lines
