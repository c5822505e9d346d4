"""A candidate effect written as an effect file of the open-effect mechanism.

A friction group becomes a ``Friction`` with ``slip`` and ``stick``, the motor's voltage an ``Input`` (the
voltage the motor sees, from the voltage entering it), a sensor's reading a ``Measurement`` of its channel
(:data:`.reading_terms.SENSORS`: ``theta_u``, ``theta_l``, ``X`` or ``Y``), the lateral force a lateral ``Force``
(``force(...) -> (FX, FY)``, fixed frame), any other group a ``Force``; the
regressed coefficients are the guesses and the bounds cover four times their size (and the size that would
make each term alone as large as the residual torque), so that ``drillgym identify --add-effect
FILE.py:NAME`` fits it.
"""

from __future__ import annotations

import textwrap
from dataclasses import replace
from pathlib import Path

from .motor_terms import SAT_LOWEST, width_parameter
from .reading_terms import SENSORS
from .results import Candidate

__all__ = ["write_effect_file", "write_fitted", "covering_file"]

_ARGS_FRICTION = ("T", "direction", "speed", "omega")
#: the quantities and base parameters a term's code may read, besides a friction's own arguments
_VARIABLES = (
    "X", "Y", "VX", "VY", "theta_l", "theta_u", "omega_l", "alpha", "alpha_dot", "t", "u", "brake", "Ts", "Tc", "ws",
    "delta", "bb", "ktheta",
)  # fmt: skip


def candidate_name(group: str) -> str:
    """The name of a candidate's effect in its file: ``candidate_GROUP``.

    Parameters
    ----------
    group : str
        The candidate's group of terms (``motor_voltage``, ``lateral_force``, a sensor's reading).

    Returns
    -------
    str
        The name.
    """
    return f"candidate_{group}"


def _share_line(cand: Candidate, reading: bool, lateral: bool) -> list[str]:
    """What the candidate explains, in its file's docstring: a reading's own fit (none when the whole model alone
    fitted it), else the regression's share."""
    if reading:
        fitted = cand.fit is not None
        return [f"    (its fit removes {cand.explained:.0%} of the unexplained variance)"] if fitted else []
    what = "force" if lateral else "torque"
    return [f"    (explains {cand.explained:.0%} of the residual {what}; {cand.n_samples} samples)"]


def write_effect_file(cand: Candidate, path: str | Path, name: str | None = None) -> Path:
    """Write a candidate as an effect file.

    Parameters
    ----------
    cand : Candidate
        The candidate; its ``name`` and ``effect_file`` (``path:name``, what ``--add-effect`` takes) are set.
    path : str or path
        The file (``.py``).
    name : str, optional
        The effect's name (default: ``candidate_GROUP``).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = Path(path)
    name = name or candidate_name(cand.group)
    cls = "".join(p.capitalize() for p in name.split("_"))
    voltage = cand.group == "motor_voltage"
    sensor = SENSORS.get(cand.group)
    reading = sensor is not None
    width = width_parameter(cand.group)  # the width's unit and lower bound as its terms fit it
    width_unit, width_lo = (width.unit, width.lo) if width is not None else ("V", 0.0)
    params, body, widths = [], [], []
    for i, (label, c) in enumerate(cand.terms.items(), 1):
        size = max(abs(c), cand.reach.get(label, 0.0), 1e-9)
        lowest = max(-4 * size, SAT_LOWEST) if voltage and label in cand.widths else -4 * size  # no falling voltage
        c = max(c, lowest)
        term_unit, doc = _term_doc(cand, label)
        params.append(
            f'        Parameter("{name}_c{i}", "{term_unit}", {lowest!r}, {4 * size!r}, {c!r}, {size / 2!r},\n'
            f'                  doc="{doc}", neutral=0.0),'
        )
        code = cand.codes[label]
        if label in cand.widths:  # a scanned width: fitted too, from the width found
            w = cand.widths[label]
            doc = "speed w over which the lead changes side" if reading else f"width of {label.split('(')[0]}(u, width)"
            params.append(
                f'        Parameter("{name}_w{i}", "{width_unit}", {width_lo!r}, {max(2.0, 3 * w)!r}, {w!r}, 0.1,\n'
                f'                  doc="{doc}"),'
            )
            code = code.replace("U0", f"{name}_w{i}")
            widths.append(f"{name}_w{i}")
        body.append(f"{name}_c{i} * ({code})")
    pnames = [f"{name}_c{i}" for i in range(1, len(cand.terms) + 1)] + widths
    expr = " + ".join(body)
    kind_import = "Friction" if cand.group.endswith("friction") else "Input" if voltage else "Force"
    kind_import = "Measurement" if reading else kind_import
    lateral = cand.group == "lateral_force"
    found = (
        "by its own fit" if reading else "from the residual lateral force" if lateral else "from the residual torques"
    )
    used = [v for v in _VARIABLES if _uses(cand, v)]
    lines = [
        f'"""Candidate effect written by `drillgym diagnose --candidate-out` {found}.',
        "",
        f"    {cand.expression()}",
        *([f"    {cand.reading()}"] if reading else []),
        *_share_line(cand, reading, lateral),
        *[f"    {line}" for note in cand.notes for line in textwrap.wrap(note, 100)],
        "",
        *_fit_it(cand, path.name, name),
        '"""',
        "",
        "import math",
        "",
        f"from drillgym.effects import {kind_import}, Parameter",
        "",
        "",
    ]
    friction = cand.group.endswith("friction")
    kind = kind_import
    lines.append(f"class {cls}({kind}):")
    lines.append(f'    name = "{name}"')
    if friction:
        lines.append(f'    disc = "{cand.group.split("_")[0]}"')
    elif voltage:
        lines.append('    configurations = ("upper", "torsional", "lateral", "coupled")  # the motor drives these')
    elif reading:
        lines.append(f'    channels = ("{sensor.variable}",)  # what {sensor.what} reads')
    else:
        lines.append(f'    acts_on = "{cand.group.split("_")[0]}"')
    if lateral:
        lines.append('    configurations = ("lateral", "coupled")  # the lower disc moves laterally in these')
    lines.append("    parameters = (")
    lines += params
    lines.append("    )")
    what = cand.reading() if reading else cand.expression()
    lines.append(f'    explanation = "Found {found} by drillgym diagnose: {what}."')
    signature = (
        sensor.signature if reading else f"the residual {'force' if lateral else 'torque'} this term was regressed on"
    )
    lines.append(f'    signature = "{signature}"')
    lines.append("")
    if friction:
        speed_args = ", ".join(a for a in _ARGS_FRICTION if a == "T" or _uses(cand, a))
        extra = "".join(f", {v}" for v in used)
        lines.append(f"    def slip({speed_args}{extra}, {', '.join(pnames)}):")
        lines.append(f"        return T + ({expr})")
        rest = [f"{p} * {cand.at_rest[lb]!r}" for p, lb in zip(pnames, cand.terms) if cand.at_rest[lb]]
        rest_args = [p for p, lb in zip(pnames, cand.terms) if cand.at_rest[lb]]
        if rest:
            lines.append("")
            lines.append(f"    def stick(lo, hi, {', '.join(rest_args)}):")
            lines.append(f"        d = {' + '.join(rest)}")
            lines.append("        return min(lo - d, 0.0), max(hi + d, 0.0)")
    elif voltage:
        lines.append(f"    def voltage(u, {', '.join(pnames)}):")
        lines.append(f"        return u + {expr}")
    elif reading:
        lines.append(f"    def measure({_measure_args(cand)}, {', '.join(pnames)}):")
        lines.append(f"        return {sensor.variable} + {expr}")
    elif lateral:  # each term's code is its pair (FX, FY) per unit coefficient
        lines.append(f"    def force({', '.join(used + pnames)}):")
        lines.append("        FX, FY = 0.0, 0.0")
        for p, label in zip(pnames, cand.terms):
            lines.append(f"        gx, gy = {cand.codes[label]}  # {label}")
            lines.append(f"        FX, FY = FX + {p} * gx, FY + {p} * gy")
        lines.append("        return FX, FY")
    else:
        args = ", ".join(used)
        lines.append(f"    def torque({args + ', ' if args else ''}{', '.join(pnames)}):")
        lines.append(f"        return {expr}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    cand.name, cand.effect_file = name, f"{path}:{name}"
    return path


def write_fitted(cand: Candidate, values: dict[str, float]) -> str:
    """Write a candidate's file again with fitted values as its coefficients and widths (their guesses, and the
    bounds around them), where it was written: a model that holds the file at values its regressed bounds do not
    cover reads it back.

    Parameters
    ----------
    cand : Candidate
        The candidate, its file written (``name`` and ``effect_file`` set).
    values : dict of str to float
        Values by the file's parameter names (``NAME_c<i>``, ``NAME_w<i>``); those missing keep the file's.

    Returns
    -------
    str
        The file's spec (``path.py:NAME``), the same as before.
    """
    path, _, name = str(cand.effect_file).rpartition(":")
    terms = {lb: values.get(f"{name}_c{i}", c) for i, (lb, c) in enumerate(cand.terms.items(), 1)}
    widths = {
        lb: values.get(f"{name}_w{i}", cand.widths[lb]) for i, lb in enumerate(cand.terms, 1) if lb in cand.widths
    }
    fitted = replace(cand, terms=terms, widths=widths)
    write_effect_file(fitted, path, name)
    return str(fitted.effect_file)


def covering_file(cand: Candidate, values: dict[str, float]) -> str:
    """The candidate's file, written again around ``values`` (:func:`write_fitted`) where one lies outside its
    parameter's range: a fit through the group's terms, whose bounds are the group's, can take a coefficient or
    a width beyond the bounds the file was written with, and a model holding the file at those values must read
    back.  The file as it is otherwise.

    Parameters
    ----------
    cand : Candidate
        The candidate, its file written.
    values : dict of str to float
        Values by the file's parameter names; others are ignored.

    Returns
    -------
    str
        The file's spec (``path.py:NAME``).
    """
    from .effects import get_effect

    own = {p.name: p for p in get_effect(cand.effect_file).parameters}
    mine = {n: v for n, v in values.items() if n in own}
    if all(own[n].lo <= v <= own[n].hi for n, v in mine.items()):
        return str(cand.effect_file)
    return write_fitted(cand, mine)


def _term_doc(cand: Candidate, label: str) -> tuple[str, str]:
    """A term's coefficient's unit and doc in the file: a reading's as its terms' effect has them (the scale
    error k is dimensionless), another candidate's in its unit, "coefficient of LABEL"."""
    sensor = SENSORS.get(cand.group)
    if sensor is None:
        return cand.unit, f"coefficient of {label}"
    p = next(p for p in sensor.effect.parameters if p.name == sensor.terms[label])
    return p.unit, f"{p.doc} ({label})"


def _measure_args(cand: Candidate) -> str:
    """A reading's ``measure`` arguments before its parameters: the channel read, and the disc's speed when a
    term reads it (the play)."""
    sensor = SENSORS[cand.group]
    speed = [sensor.speed] if sensor.speed and _uses(cand, sensor.speed) else []
    return ", ".join([sensor.variable, *speed])


def _uses(cand: Candidate, var: str) -> bool:
    import re

    return any(re.search(rf"\b{var}\b", cand.codes[lb]) for lb in cand.terms)


def _fit_it(cand: Candidate, file_name: str, name: str) -> list[str]:
    """The docstring's lines on how to fit the candidate (with the lag its terms were found through, if any)."""
    if cand.through_lag is None:
        return [f"Fit it: drillgym identify RECORDING --add-effect {file_name}:{name} --out p.json"]
    return [
        f"Its terms act on the voltage after a motor lag (about {cand.through_lag * 1e3:.0f} ms found): fit both,",
        "the lag first on the signal path:",
        f"drillgym identify RECORDING --add-effect motor_lag --add-effect {file_name}:{name} --out p.json",
    ]
