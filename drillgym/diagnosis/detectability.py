"""What the recording's input can show at all: detectability by sensitivity.

Before anything is fitted, every effect of the search model (:class:`.search_model.SearchModel`: each
candidate at its neutral values, and those the recording cannot excite held there too) is switched on at a
typical size, and every base parameter the configuration re-identifies (:data:`.search_model.BASE_FREE`) is
moved by ±5 %, all from the nominal vector and in one batched evaluation of the residual
(:meth:`~drillgym.identification.fitting.Objective.residual_matrix`; no fit).  Each row's change of the
residual vector, in noise units per channel, says how much the recording would show it:

* an effect's typical size is each of its parameters moved by its declared ``scale`` (the "typical
  magnitude" of :class:`~drillgym.effects.base.Parameter`) from its neutral value, into its bounds: a 20 ms
  motor lag, a 20 ms delay, a 5 % position friction, ...;
* an effect whose change is below :data:`DETECTABLE_RMS` noise units RMS cannot be told from this recording
  at that size; neither can one whose change the re-identified base parameters take up (what is left of it
  once its least-squares projection on the base parameters' changes is removed is below the threshold: on a
  ramp a motor lag is a voltage offset the upper friction partly takes);
* a base parameter whose ±5 % change moves the prediction by less than :data:`DETECTABLE_RMS` is not
  identifiable from this recording (a brake that never lets the lower disc slip: Ts, Tc, ws, delta, bb);
* two effects shift the response alike when the part of either's change that neither the other (at any
  size) nor the re-identified base parameters can take is below :data:`DETECTABLE_RMS`; the cosine of the two
  changes is reported beside it.  The cosine alone does not decide: on 20 s of voltage steps a 20 ms lag and a
  20 ms delay have a cosine of 0.988 and still differ by 15 noise units RMS (10 beyond the base parameters),
  on a slow ramp their cosine is 0.999998 and they differ by 0.2 (0.09).  A pair alike on the comparison grid
  is evaluated again at the recordings' own rate when they have one (500 Hz to 1 kHz,
  :func:`.timing.fine_experiments`; nominal and the pair's rows only, the base held as the lag/delay check
  holds it) and kept only when it is alike there too.

An RMS is an average over the compared samples: a difference confined to the first tens of ms after a few
steps is diluted by the samples between them (20 s of five steps at 1 kHz: a 20 ms lag and delay differ by
0.29 noise units RMS on 39,190 samples).  Such a pair is said alike here, while the lag/delay check at the
recording's rate may still decide it by its nats; :meth:`.results.Diagnosis.text` then leaves the pair's line out.

Each "cannot" comes with the experiment that would show it: the effect class's ``revealed_by`` attribute
when it has one (a user's effect file may set it), else the library effect's hint here
(:data:`REVEALED_BY`), else its kind's default (:data:`KIND_DEFAULT`); base parameters have theirs
(:data:`BASE_REVEALED_BY`).  The cost is one residual evaluation of 1 + (effects) + 2 (base parameters)
rows, and on a recording of 500 Hz or more with alike pairs one of 1 + (their effects) rows (figures in
docs/model_vs_measurement.md).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..effects import Effect
from ..identification.fitting import Objective
from .effects import label_effects
from .search_model import selection_model
from .segments import robust_noise
from .timing import fine_experiments

if TYPE_CHECKING:
    from .state import Screening

__all__ = [
    "DETECTABLE_RMS",
    "BASE_STEP",
    "KIND_DEFAULT",
    "REVEALED_BY",
    "BASE_REVEALED_BY",
    "Sensitivity",
    "AlikePair",
    "Detectability",
    "detectability",
    "revealed_by",
    "typical_values",
]

#: a change of the prediction (noise units RMS over the compared samples) below which the recording cannot
#: show it: a change a fit cannot miss against white noise is far smaller, but the nominal model's own error
#: on drillgym's clean synthetic recordings is 3-17 noise units RMS, and a change below that is lost in it
DETECTABLE_RMS = 3.0
#: relative change of a base parameter (±5 %)
BASE_STEP = 0.05
#: the experiment that shows an effect of each kind, when the effect names none
KIND_DEFAULT = {
    "delay": "voltage steps recorded at 500 Hz or faster (a delay shows in the first samples after each step)",
    "input": "voltage steps of several sizes recorded at 500 Hz or faster (fast changes of the voltage)",
    "force": "a recording in which what it acts on moves over a wide range of speeds and positions",
    "friction": "a recording in which the disc it acts on slips and sticks over a range of speeds",
    "measurement": "a recording in which the channels it changes move over their whole range",
}
_STEPS_1KHZ = (
    "voltage steps recorded at 1 kHz (after each step a lag rounds the response's first tens of ms, a delay "
    "holds all of it back)"
)
#: the library effects' own hints (kept here: drillgym/effects/library.py keys every compiled kernel package,
#: a hint there would recompile them all); an effect class may set its own ``revealed_by``
REVEALED_BY = {
    **dict.fromkeys(("motor_lag", "input_delay"), _STEPS_1KHZ),
    "position_friction": "several slow revolutions of the lower disc against the brake (a lower-disc angle)",
    "brake_asymmetry": "voltage steps of both signs that turn the lower disc backwards",
    "string_damping": "steps that leave the string oscillating (torsional oscillations after the slips)",
    "friction_drift": "a long run with the brake on (minutes: the oil warms up)",
    "lateral_anisotropy": "whirl with large orbits recorded by both LVDTs",
    "lateral_coulomb": "whirl near the lateral resonance, and small lateral motions that die out",
    "lvdt_offset": "LVDT readings with the disc at rest and whirling",
    "lvdt_skew": "whirl with large orbits recorded by both LVDTs",
}
_MOTOR = "voltage steps of several sizes that keep the upper disc turning"
_BRAKE = "voltages that make the lower disc stick and slip against the brake (several slip speeds)"
_STRING = "steps that make the lower disc slip and the string oscillate"
_BEARING = "the lower disc turning on its bearing with the brake off"
_LATERAL = "whirl: the lower disc turning fast enough to move laterally (both LVDTs)"
#: the experiment that identifies each base parameter
BASE_REVEALED_BY = {
    **dict.fromkeys(("km", "Tcu", "bu"), _MOTOR),
    **dict.fromkeys(("dTcu", "dbu"), "voltage steps of both signs (the upper disc turning both ways)"),
    **dict.fromkeys(("Ts", "Tc", "ws", "delta", "bb"), _BRAKE),
    **dict.fromkeys(("ktheta", "Jl"), _STRING),
    **dict.fromkeys(("Tcl", "bl"), _BEARING),
    **dict.fromkeys(("k", "b", "e"), _LATERAL),
}
_BASE_DEFAULT = "a recording in which this parameter's part of the model acts (see docs/model_vs_measurement.md)"


def revealed_by(effect: type[Effect]) -> str:
    """The experiment that would show an effect.

    Parameters
    ----------
    effect : Effect class
        The effect.

    Returns
    -------
    str
        Its ``revealed_by`` class attribute when set, else the library's hint (:data:`REVEALED_BY`), else
        its kind's default (:data:`KIND_DEFAULT`).
    """
    own = getattr(effect, "revealed_by", "")
    if isinstance(own, str) and own.strip():
        return " ".join(own.split())
    return REVEALED_BY.get(effect.name) or KIND_DEFAULT.get(effect.kind, KIND_DEFAULT["force"])


def typical_values(effect: type[Effect], current: dict[str, float]) -> dict[str, float]:
    """An effect switched on at a typical size: each parameter moved by its ``scale`` from its current value.

    Parameters
    ----------
    effect : Effect class
        The effect.
    current : dict of str to float
        Its parameters' current (neutral) values.

    Returns
    -------
    dict of str to float
        Parameter -> value (its unit): current + scale, or current − scale when that leaves the bounds.
    """
    out = {}
    for p in effect.parameters:
        v = current[p.name] + p.scale
        if v > p.hi:
            v = current[p.name] - p.scale
        out[p.name] = float(min(max(v, p.lo), p.hi))
    return out


@dataclass(frozen=True)
class Sensitivity:
    """How much one effect or base parameter moves the prediction.

    Attributes
    ----------
    name : str
        The effect or base parameter.
    kind : str
        The effect's kind, or ``"base"``.
    size : dict of str to float
        The values switched on (effect) or the ±step (base parameter), in their units.
    change_rms : float
        RMS of the residual's change (noise units); a base parameter: the larger of its +/− steps.
    beyond_base : float
        An effect: the part of its change the re-identified base parameters cannot take (noise units RMS;
        ``change_rms`` when the base is held).  A base parameter: ``change_rms``.
    detectable : bool
        ``beyond_base`` ≥ :data:`DETECTABLE_RMS`.
    hint : str
        The experiment that would show it.
    """

    name: str
    kind: str
    size: dict[str, float]
    change_rms: float
    beyond_base: float
    detectable: bool
    hint: str

    def line(self) -> str:
        """What cannot be told, in one line (for one that is not detectable)."""
        if self.kind == "base":
            what = f"cannot identify {self.name} from this recording: ±{100 * BASE_STEP:.0f} % of it moves"
        else:
            size = ", ".join(f"{k} {v:.3g}" for k, v in self.size.items())
            what = f"cannot tell {self.name} from this recording: at a typical size ({size}) it moves"
        line = f"{what} the prediction by {self.change_rms:.2g} noise units RMS"
        if self.change_rms >= DETECTABLE_RMS:
            line += f", but the re-identified base parameters take all but {self.beyond_base:.2g} of it"
        return f"{line} (below {DETECTABLE_RMS:g}); would show it: {self.hint}"

    def to_json(self) -> dict:
        """``{name, kind, size, change_rms, beyond_base, detectable, hint}``."""
        return {
            "name": self.name,
            "kind": self.kind,
            "size": dict(self.size),
            "change_rms": self.change_rms,
            "beyond_base": self.beyond_base,
            "detectable": self.detectable,
            "hint": self.hint,
        }


@dataclass(frozen=True)
class AlikePair:
    """Two effects whose changes of the prediction this recording cannot tell apart.

    Attributes
    ----------
    first, second : str
        The effects.
    cosine : float
        Cosine of their two changes of the residual vector.
    apart_rms : float
        The part of either's change that neither the other nor the re-identified base parameters can take,
        the smaller of the two (noise units RMS; below :data:`DETECTABLE_RMS`).
    hint : str
        The experiment that would tell them apart.
    """

    first: str
    second: str
    cosine: float
    apart_rms: float
    hint: str

    def line(self) -> str:
        """The pair in one line."""
        return (
            f"cannot tell {self.first} from {self.second} in this recording: they shift this response alike "
            f"(cosine {self.cosine:.4f}; {self.apart_rms:.2g} noise units RMS tell them apart, below "
            f"{DETECTABLE_RMS:g}); would tell them apart: {self.hint}"
        )

    def to_json(self) -> dict:
        """``{first, second, cosine, apart_rms, hint}``."""
        return {
            "first": self.first,
            "second": self.second,
            "cosine": self.cosine,
            "apart_rms": self.apart_rms,
            "hint": self.hint,
        }


@dataclass(frozen=True)
class Detectability:
    """What the recording's input can show: each effect, each re-identified base parameter, the alike pairs.

    Attributes
    ----------
    effects : tuple of Sensitivity
        The search model's effects (candidates and those held at their neutral values), the model's own left out.
    base : tuple of Sensitivity
        The base parameters re-identified.
    alike : tuple of AlikePair
        Pairs of detectable effects that shift the response alike.
    threshold : float
        :data:`DETECTABLE_RMS` (noise units RMS).
    rows : int
        Parameter rows evaluated (in one batch).
    """

    effects: tuple[Sensitivity, ...]
    base: tuple[Sensitivity, ...]
    alike: tuple[AlikePair, ...]
    threshold: float = DETECTABLE_RMS
    rows: int = 0

    def cannot(self) -> list[Sensitivity]:
        """The effects and base parameters this recording cannot show."""
        return [s for s in self.effects + self.base if not s.detectable]

    def lines(self, decided: Collection[frozenset[str]] = (), said: Collection[str] = ()) -> list[str]:
        """One line per effect, base parameter or pair this recording cannot tell (nothing else).

        Parameters
        ----------
        decided : collection of frozenset of str, optional
            Pairs a finer check decided after all (the lag/delay check at the recording's rate, not a tie):
            left out.
        said : collection of str, optional
            Effects the diagnosis already says why it did not try (skipped): left out.

        Returns
        -------
        list of str
            The lines.
        """
        pairs = [p for p in self.alike if frozenset((p.first, p.second)) not in decided]
        return [s.line() for s in self.cannot() if s.name not in said] + [p.line() for p in pairs]

    def to_json(self) -> dict:
        """The sensitivities and pairs as a JSON-ready dict."""
        return {
            "threshold_rms": self.threshold,
            "base_step": BASE_STEP,
            "effects": {s.name: s.to_json() for s in self.effects},
            "base": {s.name: s.to_json() for s in self.base},
            "alike": [p.to_json() for p in self.alike],
            "rows": self.rows,
        }


def detectability(screening: Screening) -> Detectability:
    """What the screened recording can show: one batched residual evaluation, no fit (module docstring).

    Parameters
    ----------
    screening : Screening
        The screened recording and its search model (before the selection reweights the sensors: the
        residual is in noise units).

    Returns
    -------
    Detectability
        The sensitivities of the effects and base parameters, and the pairs of effects that look alike.
    """
    m = screening.model
    comp, nominal = m.comp, np.asarray(m.nominal, dtype=float)
    own = set(label_effects(screening.model_label))
    effects = [e for e in comp.effects if e.name not in own and e.parameters]
    rows, sizes = [nominal], []
    for e in effects:
        vals = typical_values(e, {p.name: float(nominal[comp.param_index(p.name)]) for p in e.parameters})
        rows.append(_with(comp, nominal, vals))
        sizes.append(vals)
    steps = {}
    for n in m.base_names:
        step = _base_step(comp, n, float(nominal[comp.param_index(n)]))
        if step > 0.0:
            steps[n] = step
            v0 = float(nominal[comp.param_index(n)])
            rows += [_with(comp, nominal, {n: v0 + step}), _with(comp, nominal, {n: v0 - step})]
    R = m.obj.residual_matrix(np.asarray(rows))
    D = R[1:] - R[0]
    rms = np.sqrt(np.mean(D**2, axis=1)) if D.shape[1] else np.zeros(len(D))
    ne = len(effects)
    central = (D[ne::2] - D[ne + 1 :: 2]) / 2.0  # the base parameters' changes, linearised
    basis = _basis(central[np.sqrt(np.mean(central**2, axis=1)) > 1e-3].T)  # those that move it at all
    beyond = [D[i] - basis @ (basis.T @ D[i]) for i in range(ne)]
    left = [_rms(b) for b in beyond]
    eff = tuple(
        Sensitivity(e.name, e.kind, sizes[i], float(rms[i]), left[i], left[i] >= DETECTABLE_RMS, revealed_by(e))
        for i, e in enumerate(effects)
    )
    base = []
    for j, (n, step) in enumerate(steps.items()):
        ch = float(max(rms[ne + 2 * j], rms[ne + 2 * j + 1]))
        base.append(
            Sensitivity(n, "base", {n: step}, ch, ch, ch >= DETECTABLE_RMS, BASE_REVEALED_BY.get(n, _BASE_DEFAULT))
        )
    alike = _alike(eff, effects, D[:ne], beyond)
    if alike:  # what the comparison grid shows alike, the recording's own rate may tell apart
        alike = _fine_recheck(screening, alike, {e.name: rows[1 + i] for i, e in enumerate(effects)})
    return Detectability(eff, tuple(base), alike, DETECTABLE_RMS, len(rows))


def _alike(eff, effects, changes, beyond) -> tuple[AlikePair, ...]:
    """The pairs of detectable effects whose changes tell them apart by less than the threshold."""
    out = []
    for i in range(len(eff)):
        for j in range(i + 1, len(eff)):
            if not (eff[i].detectable and eff[j].detectable):
                continue
            apart = min(_rms(_off(beyond[i], beyond[j])), _rms(_off(beyond[j], beyond[i])))
            if apart >= DETECTABLE_RMS:
                continue
            a, b = changes[i], changes[j]
            cos = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
            hints = list(dict.fromkeys((eff[i].hint, eff[j].hint)))
            out.append(AlikePair(effects[i].name, effects[j].name, cos, apart, "; ".join(hints)))
    return tuple(out)


def _fine_recheck(screening: Screening, alike: tuple[AlikePair, ...], on: dict[str, np.ndarray]) -> tuple:
    """The pairs still alike at the recordings' own rate (up to 1 kHz, base held as the lag/delay check holds
    it); all of them when the recordings are slower than 500 Hz (:func:`.timing.fine_experiments`)."""
    fine = fine_experiments(screening.exps)
    if fine is None:
        return alike
    m = screening.model
    conditioned = [robust_noise(ex) for ex in fine]
    scales = {c: min(sc[c] for _, sc in conditioned) for c in conditioned[0][1]}
    obj = Objective(selection_model([c[0] for c in conditioned], screening.segment_s, m.comp), m.obj.weights, scales)
    names = list(dict.fromkeys(n for p in alike for n in (p.first, p.second)))
    R = obj.residual_matrix(np.asarray([m.nominal] + [on[n] for n in names]))
    D = dict(zip(names, R[1:] - R[0]))
    return tuple(
        p
        for p in alike
        if min(_rms(_off(D[p.first], D[p.second])), _rms(_off(D[p.second], D[p.first]))) < DETECTABLE_RMS
    )


def _with(comp, nominal: np.ndarray, values: dict[str, float]) -> np.ndarray:
    """The nominal vector with some parameters set."""
    v = nominal.copy()
    for k, x in values.items():
        v[comp.param_index(k)] = x
    return v


def _base_step(comp, name: str, value: float) -> float:
    """±step of a re-identified parameter: 5 % of its nominal value, or its scale when that is 0 (an
    effect's parameter freed with the base)."""
    if value != 0.0:
        return abs(BASE_STEP * value)
    for e in comp.effects:
        for p in e.parameters:
            if p.name == name:
                return float(p.scale)
    return 0.0


def _basis(cols: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the span of the columns (M, k), rank-revealing; (M, 0) when none."""
    if cols.ndim != 2 or cols.size == 0:
        return np.zeros((cols.shape[0], 0))
    u, s, _ = np.linalg.svd(cols, full_matrices=False)
    return u[:, s > s.max() * 1e-9] if s.size and s.max() > 0 else np.zeros((cols.shape[0], 0))


def _off(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` with its projection on ``b`` removed."""
    bb = float(b @ b)
    return a - (a @ b / bb) * b if bb > 0 else a


def _rms(x: np.ndarray) -> float:
    """Root mean square (0 for an empty vector)."""
    return float(np.sqrt(np.mean(x**2))) if x.size else 0.0
