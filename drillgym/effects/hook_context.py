"""Writing the hooks of a composition, part 1: an effect's arguments as kernel expressions.

An effect function names its arguments from a fixed vocabulary (its own parameters and states, the
base parameters, ``t``, ``u``, the mechanical states, ``alpha``, the fixed-frame ``X``/``Y``/
``VX``/``VY``, a friction effect's disc quantities). :class:`HookContext` turns each name into an
expression of the scalar or the lane kernel; the functions below write the calls and the guards
(configuration, switch) around them for :mod:`drillgym.effects.hookgen`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..params import IDX
from .base import Effect

if TYPE_CHECKING:  # pragma: no cover
    from .composition import Composition

__all__ = [
    "HookContext",
    "call_effect",
    "fixed_frame_prologue",
    "prologue",
    "cfg_guard",
    "switch_rows",
    "switch_condition",
    "both",
    "guarded",
    "JIT",
    "CFG_CODES",
]

#: configuration codes of the compiled kernels
CFG_CODES = {"upper": 0, "torsional": 1, "lateral": 2, "coupled": 3, "free_vibration": 4}
#: the decorator of every generated hook and effect function (the flags: :data:`drillgym.vmath.FASTMATH`)
JIT = 'njit(inline="always", fastmath={"nnan", "ninf", "nsz"}, error_model="numpy")'


class HookContext:
    """Expressions for the quantities of the effects' vocabulary in one kernel variant.

    Parameters
    ----------
    lane : bool
        The lane (SIMD, structure-of-arrays) variant, else the scalar one.
    comp : Composition
        The composition of effects.
    effect_index : int
        The effect whose arguments are resolved.
    disc : str, optional
        ``"upper"`` or ``"lower"`` for a friction effect's disc quantities.

    Attributes
    ----------
    needs_fixed : bool
        Set when a resolved argument reads the fixed-frame quantities (``X``, ``Y``, ``VX``,
        ``VY``): the hook then computes them in its prologue.
    """

    def __init__(self, lane: bool, comp: Composition, effect_index: int, disc: str | None = None):
        self.lane = lane
        self.comp = comp
        self.i = effect_index
        self.disc = disc
        self.needs_fixed = False

    def param(self, index: int) -> str:
        return f"PT[{index}, k]" if self.lane else f"p[{index}]"

    def state(self, j: int) -> str:
        return f"Y[nm + {j}, k]" if self.lane else f"y[{8 + j}]"

    def mech(self, name: str) -> str:
        lane = {
            "theta_u": "thu",
            "theta_l": "thl",
            "omega_u": "wu",
            "omega_l": "wl",
            "x": "x",
            "y": "yy",
            "vx": "vx",
            "vy": "vy",
        }
        scalar = {
            "theta_u": "y[0]",
            "theta_l": "y[1]",
            "omega_u": "y[2]",
            "omega_l": "y[3]",
            "x": "y[4]",
            "y": "y[5]",
            "vx": "y[6]",
            "vy": "y[7]",
        }
        return (lane if self.lane else scalar)[name]

    def resolve(self, arg: str, chain_u: str = "u") -> str:
        eff = self.comp.effects[self.i]
        own = {p.name: self.comp.param_index(p.name) for p in eff.parameters}
        states = {s.name: self.comp.state_index(s.name) for s in eff.states}
        if arg in own:
            return self.param(own[arg])
        if arg in states:
            return self.state(states[arg])
        if arg in IDX.__dict__:
            return self.param(getattr(IDX, arg))
        if arg == "t":
            return "t"
        if arg == "u":
            return chain_u
        if arg in ("theta_u", "theta_l", "omega_u", "omega_l", "x", "y", "vx", "vy"):
            return self.mech(arg)
        if arg == "alpha":
            return f"({self.mech('theta_l')} - {self.mech('theta_u')})"
        if arg == "alpha_dot":
            return f"({self.mech('omega_l')} - {self.mech('omega_u')})"
        if arg in ("X", "Y", "VX", "VY"):
            self.needs_fixed = True
            return f"_{arg}"
        if arg == "brake":
            return "brake"
        if self.disc is not None:
            if arg == "T":
                return "T"
            if arg == "direction":
                return "d"
            if arg == "speed":
                return "aw"
            if arg == "omega":
                return self.mech("omega_u" if self.disc == "upper" else "omega_l")
            if arg == "theta":
                return self.mech("theta_u" if self.disc == "upper" else "theta_l")
            if arg in ("lo", "hi"):
                return arg
        raise KeyError(arg)  # validation (composition.validate_effect) reports it with the file name


def call_effect(comp: Composition, ctx: HookContext, fn: str, chain_u: str = "u") -> str:
    """The call of one function of an effect, its arguments resolved in a kernel variant.

    Parameters
    ----------
    comp : Composition
        The composition of effects.
    ctx : HookContext
        The effect and kernel variant.
    fn : str
        The effect's function (``"voltage"``, ``"torque"``, ``"slip"``, ...).
    chain_u : str, optional
        The expression of the voltage ``u`` at this point of the input chain.

    Returns
    -------
    str
        Python source of the call.
    """
    eff = comp.effects[ctx.i]
    args = ", ".join(ctx.resolve(a, chain_u) for a in eff.argument_names(fn))
    return f"_e{ctx.i}_{fn}{'_v' if ctx.lane else ''}({args})"


def fixed_frame_prologue(lane: bool) -> list[str]:
    """Source lines computing the fixed-frame position and velocity (``_X``, ``_Y``, ``_VX``, ``_VY``)."""
    if lane:
        return [
            "_st, _ct = vsincos(thu)",
            "_X = x * _ct - yy * _st",
            "_Y = x * _st + yy * _ct",
            "_VX = _ct * vx - _st * vy - _Y * wu",
            "_VY = _st * vx + _ct * vy + _X * wu",
        ]
    return [
        "_ct = math.cos(y[0])",
        "_st = math.sin(y[0])",
        "_X = y[4] * _ct - y[5] * _st",
        "_Y = y[4] * _st + y[5] * _ct",
        "_VX = _ct * y[6] - _st * y[7] - _Y * y[2]",
        "_VY = _st * y[6] + _ct * y[7] + _X * y[2]",
    ]


def prologue(lane: bool, fixed_needed: bool, *more: str) -> list[str]:
    """The first lines of a hook: the fixed-frame quantities when an effect reads them, the brake
    flag, then ``more``."""
    return (fixed_frame_prologue(lane) if fixed_needed else []) + [
        "brake = 1.0 if (cfg == 1 or cfg == 3) else 0.0",
        *more,
    ]


def cfg_guard(eff: type[Effect]) -> str | None:
    """The condition on ``cfg`` under which an effect applies; None when it applies to every configuration."""
    cfgs = [CFG_CODES[c] for c in eff.configurations]
    if len(cfgs) == len(CFG_CODES):
        return None
    return " or ".join(f"cfg == {c}" for c in cfgs) if cfgs else "False"


def switch_rows(comp: Composition) -> dict[int, int]:
    """Rows of the effects' switches in the lane parameter matrix, after the parameter rows.

    Parameters
    ----------
    comp : Composition
        The composition of effects.

    Returns
    -------
    dict of int to int
        Effect index to row, for the effects that declare where they vanish
        (:meth:`Effect.neutral_values`).
    """
    out: dict[int, int] = {}
    for i, eff in enumerate(comp.effects):
        if eff.neutral_values() is not None:
            out[i] = comp.n_params + len(out)
    return out


def switch_condition(comp: Composition, lane: bool, i: int) -> str | None:
    """The condition under which effect ``i`` runs; None when it always runs.

    Skipping is exact because the effect adds nothing at its neutral values. Scalar kernels test
    the run's own parameters; lane kernels read the batch's switch (on when any lane's parameters
    leave the neutral values), so the branch is the same in every lane and the loops stay
    vectorised.
    """
    row = switch_rows(comp).get(i)
    if row is None:
        return None
    if lane:
        return f"PT[{row}, 0] != 0.0"
    return " or ".join(f"p[{comp.param_index(n)}] != {v!r}" for n, v in comp.effects[i].neutral_values().items())


def both(*conds: str | None) -> str | None:
    """The conjunction of the given conditions (None ones left out); None when none is left."""
    conds = tuple(c for c in conds if c)
    if not conds:
        return None
    return conds[0] if len(conds) == 1 else " and ".join(f"({c})" for c in conds)


def guarded(lines: list[str], cond: str | None) -> list[str]:
    """Source lines under ``if cond:`` (unchanged when ``cond`` is None or there are no lines)."""
    if cond is None or not lines:
        return lines
    return [f"if {cond}:"] + ["    " + ln for ln in lines]
