"""What an effect function may ask for: the quantities behind its argument names, by kind and function.

An effect function names its arguments after the quantities it needs (:mod:`drillgym.effects.base`).
Besides the effect's own parameters and states, and the base parameters
(:data:`drillgym.params.PARAM_NAMES`), a function may ask for the fixed quantities of
:func:`quantity_table`; which ones depends on the kind and the function (a Friction effect's ``slip``
gets its disc's slip torque ``T``, a Measurement's ``measure`` the channels only, a Delay's ``delay``
parameters only).  The validation's "unknown quantity" message and docs/EFFECTS.md both come from here.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..params import PARAM_INFO, PARAM_NAMES
from .base import FRICTION_VOCABULARY, MEASUREMENT_CHANNELS, VOCABULARY, Effect

__all__ = [
    "Quantity",
    "QUANTITY_UNITS",
    "KIND_FUNCTIONS",
    "fixed_quantities",
    "allowed_arguments",
    "quantity_table",
    "quantities_markdown",
    "base_parameters_markdown",
    "describe_allowed",
]

#: every function an effect of a kind may define (``derivative`` only with ``states``; a Measurement has none)
KIND_FUNCTIONS: dict[str, tuple[str, ...]] = {
    "Force": ("torque", "force", "derivative"),
    "Friction": ("slip", "stick", "level", "derivative"),
    "Input": ("voltage", "derivative"),
    "Delay": ("delay",),
    "Measurement": ("measure",),
}

#: units of the fixed quantities
QUANTITY_UNITS: dict[str, str] = {
    "t": "s",
    "u": "V",
    "theta_u": "rad",
    "theta_l": "rad",
    "omega_u": "rad/s",
    "omega_l": "rad/s",
    "alpha": "rad",
    "alpha_dot": "rad/s",
    "x": "m",
    "y": "m",
    "vx": "m/s",
    "vy": "m/s",
    "X": "m",
    "Y": "m",
    "VX": "m/s",
    "VY": "m/s",
    "brake": "-",
    "T": "N m",
    "direction": "-",
    "speed": "rad/s",
    "omega": "rad/s",
    "theta": "rad",
    "lo": "N m",
    "hi": "N m",
}
_CHANNEL_MEANING = {
    "theta_u": "upper disc angle as measured so far (rad)",
    "theta_l": "lower disc angle as measured so far (rad)",
    "X": "lateral position x of the lower disc centre as measured so far, fixed frame (m)",
    "Y": "lateral position y as measured so far, fixed frame (m)",
}
#: what ``Measurement.measure`` may read besides the channels: the discs' speeds (a reading that depends on the
#: direction of motion: backlash between the encoder's shaft and the disc)
MEASURE_SPEEDS = ("omega_u", "omega_l")


@dataclass(frozen=True)
class Quantity:
    """A fixed quantity an effect function may name as an argument.

    Attributes
    ----------
    name : str
        The argument name.
    unit : str
        Its SI unit.
    meaning : str
        What it is.
    functions : tuple of str
        The functions that may ask for it, as ``"Kind.function"`` (e.g. ``"Friction.slip"``).
    """

    name: str
    unit: str
    meaning: str
    functions: tuple[str, ...]


def fixed_quantities(kind: str, function: str) -> dict[str, str]:
    """The fixed quantities (name -> meaning) one function of one kind may ask for.

    Parameters
    ----------
    kind : str
        ``"Force"``, ``"Friction"``, ``"Input"``, ``"Delay"`` or ``"Measurement"`` (or the lower-case kind).
    function : str
        One of the kind's functions (:data:`KIND_FUNCTIONS`).

    Returns
    -------
    dict of str to str
        Name -> meaning, besides the effect's own parameters and states and the base parameters.
    """
    if not isinstance(kind, str) or not isinstance(function, str):
        return {}
    kind = kind.capitalize()
    if kind == "Measurement":
        if function != "measure":
            return {}
        return {c: _CHANNEL_MEANING[c] for c in MEASUREMENT_CHANNELS} | {w: VOCABULARY[w] for w in MEASURE_SPEEDS}
    if kind == "Delay" and function == "delay":
        return {}
    out = dict(VOCABULARY)
    if kind == "Friction":
        out.pop("u")
        drop = {
            "slip": {"lo", "hi"},
            "stick": {"T", "direction", "speed"},
            "level": {"T", "lo", "hi", "direction", "speed"},
        }.get(function, set(FRICTION_VOCABULARY))  # derivative: no disc quantities
        out.update({k: v for k, v in FRICTION_VOCABULARY.items() if k not in drop})
    return out


def allowed_arguments(cls: type[Effect], function: str) -> set[str]:
    """Every argument name ``function`` of effect class ``cls`` may use: its parameters and states, the base
    parameters and the fixed quantities of its kind and function (:func:`fixed_quantities`)."""
    own = {p.name for p in cls.parameters} | {s.name for s in cls.states}
    kind = next((k for k in KIND_FUNCTIONS if cls.kind == k.lower()), cls.kind)
    return own | set(PARAM_NAMES) | set(fixed_quantities(kind, function))


def describe_allowed(cls: type[Effect], function: str) -> str:
    """In words, what ``function`` of ``cls`` may ask for (the validation's "unknown quantity" message)."""
    params = ", ".join(p.name for p in cls.parameters) or "none"
    states = ", ".join(s.name for s in cls.states) or "none"
    kind = cls.kind.capitalize()
    fixed = ", ".join(fixed_quantities(kind, function)) or "nothing else"
    return (
        f"a {kind} effect's {function}() may ask for its parameters ({params}), its states ({states}), "
        f"the base parameters ({', '.join(PARAM_NAMES)}) and: {fixed} (docs/EFFECTS.md lists them)"
    )


def quantity_table() -> list[Quantity]:
    """Every fixed quantity with the functions that may ask for it, in a stable order.

    Returns
    -------
    list of Quantity
        The vocabulary (:data:`drillgym.effects.base.VOCABULARY`), then the Friction functions' disc
        quantities, then the Measurement channels (under ``measure`` they are the readings so far).
    """
    names = list(VOCABULARY) + [n for n in FRICTION_VOCABULARY if n not in VOCABULARY]
    rows = []
    for n in names:
        fns = tuple(
            f"{kind}.{fn}" for kind, fs in KIND_FUNCTIONS.items() for fn in fs if n in fixed_quantities(kind, fn)
        )
        meaning = VOCABULARY.get(n) or FRICTION_VOCABULARY[n]
        rows.append(Quantity(n, QUANTITY_UNITS[n], meaning, fns))
    return rows


def _functions_text(functions: tuple[str, ...]) -> str:
    """``Kind.function`` names as Markdown code, or "every function but ..." when that is shorter."""
    every = [f"{k}.{fn}" for k, fs in KIND_FUNCTIONS.items() for fn in fs]
    left_out = [f for f in every if f not in functions]
    if left_out and len(left_out) < len(functions):
        return "every function but " + ", ".join(f"`{f}`" for f in left_out)
    return ", ".join(f"`{f}`" for f in functions)


def quantities_markdown() -> str:
    """The table of :func:`quantity_table` in Markdown (docs/EFFECTS.md holds it verbatim; a test checks it)."""
    lines = ["| name | unit | meaning | may be asked for by |", "|---|---|---|---|"]
    for q in quantity_table():
        meaning = q.meaning
        if q.name in MEASUREMENT_CHANNELS:
            meaning += "; in `measure`, the reading so far (after the Measurement effects before it)"
        lines.append(f"| `{q.name}` | {q.unit} | {meaning} | {_functions_text(q.functions)} |")
    return "\n".join(lines)


def base_parameters_markdown() -> str:
    """The base parameters as a Markdown table (name, unit, meaning): every function may ask for them."""
    lines = ["| name | unit | meaning |", "|---|---|---|"]
    for n in PARAM_NAMES:
        lines.append(f"| `{n}` | {PARAM_INFO[n]['unit']} | {PARAM_INFO[n].get('doc', '')} |")
    return "\n".join(lines)
