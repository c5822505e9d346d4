"""The library of terms discovery regresses the residual on, grouped by where they would act.

See :mod:`.discovery` for the groups and how a candidate is chosen among them; here, each term's name, its
expression in a written effect file and how it is computed from the data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from .results import Candidate

__all__ = ["COGGING_HARMONICS", "DEAD_ZONE_WIDTHS", "dead_zone_variant", "odd_form"]


@dataclass
class _Term:
    label: str  # as shown (unicode)
    code: str  # Python expression of the effect function's arguments
    values: Callable[[dict], np.ndarray]
    at_rest: float = 0.0  # value at zero speed approached from above (friction terms: stick set change)
    width: float | None = None  # a scanned width (V): the file fits it, as a parameter named in the code by U0


def _speed_terms(w: str, sym: str) -> list[_Term]:
    out = [
        _Term(f"sign({sym})", "direction", lambda d: np.sign(d[w]), 1.0),
        _Term(f"{sym}", "omega", lambda d: d[w]),
        _Term(f"{sym}|{sym}|", "omega * speed", lambda d: d[w] * np.abs(d[w])),
        _Term(f"{sym}³", "omega * omega * omega", lambda d: d[w] ** 3),
    ]
    for v in (0.3, 1.0, 3.0):
        out.append(
            _Term(
                f"sign({sym}) exp(−|{sym}|/{v:g})",
                f"direction * math.exp(-speed / {v!r})",
                lambda d, v=v: np.sign(d[w]) * np.exp(-np.abs(d[w]) / v),
                1.0,
            )
        )
    for v in (0.25, 0.5, 1.0, 1.5, 3.0):
        out.append(
            _Term(
                f"sign({sym}) exp(−({sym}/{v:g})²)",
                f"direction * math.exp(-(speed / {v!r}) ** 2)",
                lambda d, v=v: np.sign(d[w]) * np.exp(-((d[w] / v) ** 2)),
                1.0,
            )
        )
    return out


def _stribeck_terms(ws: float, delta: float) -> list[_Term]:
    """Changes of the lower disc's Stribeck shape sign(ω) exp(−(|ω|/ws)^δ): its derivatives with respect to δ
    and ws (a different exponent or Stribeck speed: first order), and the shape with other exponents (a
    different law: e.g. a Lorentzian's long tail is close to δ = 1).  Regressed at the model's ``ws``,
    ``delta``; the code reads the base parameters ``ws`` and ``delta`` themselves, so a term's effect follows
    them when they are fitted (and its compiled form is the same for every recording)."""
    out = []
    for dd in (0.5, 1.0, 3.0):
        out.append(
            _Term(
                f"sign(ωl) exp(−(|ωl|/ws)^{dd:g})",
                f"direction * math.exp(-(speed / ws) ** {dd!r})",
                lambda d, dd=dd: np.sign(d["wl"]) * np.exp(-((np.abs(d["wl"]) / ws) ** dd)),
                1.0,
            )
        )

    def dshape_ddelta(w: np.ndarray) -> np.ndarray:
        x = np.maximum(np.abs(w) / ws, 1e-12)
        return -np.sign(w) * np.exp(-(x**delta)) * x**delta * np.log(x)

    def dshape_dws(w: np.ndarray) -> np.ndarray:
        x = np.abs(w) / ws
        return np.sign(w) * np.exp(-(x**delta)) * delta * x**delta

    xs = "max(speed / ws, 1e-12)"
    out.append(
        _Term(
            "∂/∂δ of sign(ωl) exp(−(|ωl|/ws)^δ)",
            f"-direction * math.exp(-{xs} ** delta) * {xs} ** delta * math.log({xs})",
            lambda d: dshape_ddelta(d["wl"]),
        )
    )
    out.append(
        _Term(
            "ws·∂/∂ws of sign(ωl) exp(−(|ωl|/ws)^δ)",
            "direction * math.exp(-(speed / ws) ** delta) * delta * (speed / ws) ** delta",
            lambda d: dshape_dws(d["wl"]),
        )
    )
    return out


def _groups(lateral: bool, ws: float = 1.4302, delta: float = 2.0575) -> dict[str, list[_Term]]:
    lower = (
        _speed_terms("wl", "ωl")
        + _stribeck_terms(ws, delta)
        + [
            _Term("sign(ωl) cos θl", "direction * math.cos(theta_l)", lambda d: np.sign(d["wl"]) * np.cos(d["thl"])),
            _Term("sign(ωl) sin θl", "direction * math.sin(theta_l)", lambda d: np.sign(d["wl"]) * np.sin(d["thl"])),
            _Term(
                "sign(ωl) cos 2θl",
                "direction * math.cos(2.0 * theta_l)",
                lambda d: np.sign(d["wl"]) * np.cos(2 * d["thl"]),
            ),
            _Term(
                "sign(ωl) sin 2θl",
                "direction * math.sin(2.0 * theta_l)",
                lambda d: np.sign(d["wl"]) * np.sin(2 * d["thl"]),
            ),
            _Term("sign(ωl) t", "direction * t", lambda d: np.sign(d["wl"]) * d["t"]),
        ]
    )
    upper = _speed_terms("wu", "ωu")
    string = [
        _Term("α|α|", "alpha * abs(alpha)", lambda d: d["a"] * np.abs(d["a"])),
        _Term("α³", "alpha ** 3", lambda d: d["a"] ** 3),
        _Term("α⁵", "alpha ** 5", lambda d: d["a"] ** 5),
        _Term("α̇", "alpha_dot", lambda d: d["ad"]),
        _Term("sign(α̇)", "math.tanh(alpha_dot / 0.01)", lambda d: np.tanh(d["ad"] / 0.01)),
    ]
    for g in (0.02, 0.05, 0.1, 0.2, 0.5):
        string.append(_Term(f"sat(α, {g:g})", f"min(max(alpha, {-g!r}), {g!r})", lambda d, g=g: np.clip(d["a"], -g, g)))
    lower_force = [
        _Term("1", "1.0", lambda d: np.ones_like(d["t"])),
        _Term("cos θl", "math.cos(theta_l)", lambda d: np.cos(d["thl"])),
        _Term("sin θl", "math.sin(theta_l)", lambda d: np.sin(d["thl"])),
        _Term("t", "t", lambda d: d["t"]),
    ]
    upper_force = [_Term("1", "1.0", lambda d: np.ones_like(d["t"]))] + _cogging_terms()
    return {
        "lower_friction": lower,
        "upper_friction": upper,
        "string": string,
        "lower_force": lower_force,
        "upper_force": upper_force,
        "motor_voltage": _voltage_terms(),
    }


#: harmonics of the motor angle tried as a cogging torque (per revolution)
COGGING_HARMONICS = (1, 2, 3, 4, 6, 8, 12)
#: half-widths (V) of the dead zones tried: sat(u, u0) = u − sign(u) max(|u| − u0, 0)
DEAD_ZONE_WIDTHS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0)


def _cogging_terms() -> list[_Term]:
    """cos kθu and sin kθu for k in :data:`COGGING_HARMONICS`: a torque on the upper disc that depends on the
    motor angle (cogging, an eccentric load)."""
    out = []
    for k in COGGING_HARMONICS:
        arg = "theta_u" if k == 1 else f"{float(k)!r} * theta_u"
        sym = "θu" if k == 1 else f"{k}θu"
        out.append(_Term(f"cos {sym}", f"math.cos({arg})", lambda d, k=k: np.cos(k * d["thu"])))
        out.append(_Term(f"sin {sym}", f"math.sin({arg})", lambda d, k=k: np.sin(k * d["thu"])))
    return out


def _voltage_terms() -> list[_Term]:
    """Changes of the voltage the motor sees, as functions of the voltage u entering the drive: 1 (a constant offset
    of the drive), sign(u) (an offset that follows the direction), |u|, u|u| and u³ (a motor constant that depends
    on the voltage: saturation), and sat(u, u0) for the widths :data:`DEAD_ZONE_WIDTHS` (−sat(u, u0) is a dead
    zone of half-width u0: the motor sees sign(u) max(|u| − u0, 0)).  Regressed as a torque km × (change) on the
    upper disc; written as an Input effect."""
    out = [
        _Term("1", "1.0", lambda d: np.ones_like(d["u"])),
        _Term("sign(u)", "(1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0))", lambda d: np.sign(d["u"])),
        _Term("|u|", "abs(u)", lambda d: np.abs(d["u"])),
        _Term("u|u|", "u * abs(u)", lambda d: d["u"] * np.abs(d["u"])),
        _Term("u³", "u ** 3", lambda d: d["u"] ** 3),
    ]
    for u0 in DEAD_ZONE_WIDTHS:
        out.append(
            _Term(f"sat(u, {u0:g})", "min(max(u, -U0), U0)", lambda d, u0=u0: np.clip(d["u"], -u0, u0), width=u0)
        )
    return out


#: (effect on the upper disc's torque, on the lower disc's) of a unit of the term, per group
_SENSE = {
    "lower_friction": (0.0, -1.0),
    "upper_friction": (-1.0, 0.0),
    "string": (1.0, -1.0),
    "lower_force": (0.0, 1.0),
    "upper_force": (1.0, 0.0),
    "motor_voltage": (1.0, 0.0),  # per volt at the motor: times km (the coefficients are turned into volts)
}


#: the even voltage terms and their odd forms on a command of one sign s (``|u| = s u`` there)
_ODD_FORMS = {"|u|": ("u", "(-u)")}


def odd_form(cand: Candidate, u: np.ndarray) -> Candidate:
    """The motor-side candidate with its even terms written in their odd form where the command never reverses.

    On a recording whose command keeps one sign s, ``|u|`` is ``s u``: the fit cannot tell an asymmetric gain from a
    motor constant that is off, and the file's code decides what a reversed command does.  A motor constant off
    reverses with the command (odd), so ``|u|`` is written as ``s u``; written as ``abs(u)`` it made the model's
    motor push forwards on a reversed command, where a controller built on it reverses the motor (the observer
    where the lower disc breaks away; docs/model_vs_measurement.md).  The term keeps its label (its fit runs
    through the group's effect, where both forms are the same numbers on this recording); the file's docstring
    says how it is written.

    Parameters
    ----------
    cand : Candidate
        The candidate (changed in place).
    u : numpy.ndarray
        The command of the recording's samples (V).

    Returns
    -------
    Candidate
        ``cand``.
    """
    u = np.asarray(u, dtype=float)
    if cand.group != "motor_voltage" or u.size == 0:
        return cand
    sign = 1 if np.all(u >= 0.0) else (-1 if np.all(u <= 0.0) else 0)
    if sign == 0:
        return cand
    for label, (plus, minus) in _ODD_FORMS.items():
        if label in cand.terms:
            code = plus if sign > 0 else minus
            cand.codes[label] = code
            cand.notes += (
                f"{label} is written as {code}: the command never reversed on the recording, where the two are one "
                "term; a motor constant that is off reverses with the command.",
            )
    return cand


def offset_variant(cand: Candidate) -> Candidate | None:
    """The motor-side candidate with its dead zone read as a negative offset, or None when it has none (the
    converse of :func:`dead_zone_variant`: ``-sat(u, w)`` becomes the constant ``-w``)."""
    if cand.group != "motor_voltage" or "1" in cand.terms:
        return None
    zone = next((k for k in cand.widths if k.startswith("sat(u") and cand.terms.get(k, 0.0) < -0.5), None)
    if zone is None:
        return None
    return _replaced(cand, (zone,), "1", -cand.widths[zone], "1.0")


def _replaced(
    cand: Candidate, drop: tuple[str, ...], label: str, coefficient: float, code: str, width: float | None = None
) -> Candidate:
    """The candidate with its terms ``drop`` replaced by one term ``label`` (this coefficient, code and width, 0 at
    rest), the others kept: a new candidate, no file, no fit."""
    kept = [k for k in cand.terms if k not in drop]
    widths = {k: w for k, w in cand.widths.items() if k in kept}
    return replace(
        cand,
        terms={**{k: cand.terms[k] for k in kept}, label: coefficient},
        codes={**{k: cand.codes[k] for k in kept}, label: code},
        at_rest={**{k: cand.at_rest.get(k, 0.0) for k in kept}, label: 0.0},
        reach={k: v for k, v in cand.reach.items() if k in kept},
        widths=widths if width is None else {**widths, label: width},
        effect_file=None,
        fit=None,
        alternative=None,
    )


#: the voltage terms a dead zone's shift is made of where the motor turns (−w sign(u) beyond the zone)
_SHIFT_TERMS = ("1", "sign(u)")


def dead_zone_variant(cand: Candidate, u: np.ndarray | None = None) -> Candidate | None:
    """The motor-side candidate with its shift of the voltage read as one dead zone, or None when it has none.

    A dead zone of half-width ``w`` (``−sat(u, w)``) changes the voltage by ``−w sign(u)`` wherever ``|u| > w``;
    so does a constant ``−w`` on one-signed commands, a ``−w sign(u)``, and any mix of these with partial zones
    (``c sat(u, w')``, ``|c| < 1``) on the commands beyond them.  Inside the zone the motor sees no voltage and the
    upper disc mostly sticks, where the residual torques are not known, so the regression cannot tell these apart
    and takes whichever mix its greedy order meets first.  The candidate's fit on the recordings can
    (:func:`.candidate_fit.choose_candidate`): this variant puts the shift's terms (:data:`_SHIFT_TERMS` and the
    zones) together as one zone, of the width the shift has beyond all of them, the other terms kept.

    Parameters
    ----------
    cand : Candidate
        The candidate.
    u : numpy.ndarray, optional
        The recording's command (V): the width is the median shift ``−S(u) sign(u)`` over the commands beyond every
        zone of the candidate.  None: the shift just beyond the widest zone on a positive command.

    Returns
    -------
    Candidate or None
        The variant (a new candidate, no file, no fit); None when the candidate has no shift that narrows the
        voltage, or its shift is one whole zone already.
    """
    if cand.group != "motor_voltage":
        return None
    zones = {k: w for k, w in cand.widths.items() if k.startswith("sat(u") and k in cand.terms}
    shift = [k for k in cand.terms if k in _SHIFT_TERMS or k in zones]
    if not shift or (len(shift) == 1 and shift[0] in zones and cand.terms[shift[0]] <= -0.5):
        return None
    edge = max(zones.values(), default=0.0)
    beyond = np.asarray(u, dtype=float) if u is not None else np.array([edge + 1e-9])
    beyond = beyond[np.abs(beyond) > edge]
    if beyond.size == 0:
        return None
    terms = {t.label: t for t in _voltage_terms()}
    s = sum(cand.terms[k] * (np.clip(beyond, -zones[k], zones[k]) if k in zones else terms[k].values({"u": beyond}))
            for k in shift)  # fmt: skip
    width = float(np.median(-s * np.sign(beyond)))
    if not width > 0.0:
        return None
    sat = next(t for t in _voltage_terms() if t.width is not None)
    return _replaced(cand, tuple(shift), f"sat(u, {width:.3g})", -1.0, sat.code, width)
