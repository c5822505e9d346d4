"""Code generation: one compiled model per composition of effects, cached on disk by content.

For a composition (an ordered tuple of effect classes) this module writes the hooks of
:mod:`drillgym.kernels.hooks` as Python source in which every effect function is called with
the arguments its names ask for, then a specialised copy of each kernel template
(:mod:`drillgym.kernels.model`, ``stepping``, ``lanes``, and client templates such as the
environments' period kernel) that imports the generated hooks.  numba compiles them on first
use and caches the machine code next to the generated files (``cache=True``).

The files live in ``$DRILLGYM_KERNEL_CACHE`` (default ``~/.cache/drillgym/kernels``) in a
package named after a SHA-256 of everything the code depends on: the generated hooks, every
drillgym source file, the effects' own source files, numba's and Python's versions.  A changed
effect file or drillgym source gives a new package, so a cached composition is never stale.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import shutil
import sys
import tempfile
import time
from functools import lru_cache
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numba

from .._kernel_cache import modules_digest
from ..params import IDX, PARAM_NAMES
from .base import Effect, Force, Friction, Input, Delay, Measurement

if TYPE_CHECKING:  # pragma: no cover
    from .composition import Composition

__all__ = ["cache_root", "hooks_source", "build_kernels", "CORE_TEMPLATES"]

CORE_TEMPLATES = ("model", "stepping", "lanes")
# Client templates (modules whose compiled code calls the kernels; see CompiledModel.client). The
# generated packages are keyed on the sources these and the core templates import, transitively.
CLIENT_TEMPLATES = ("drillgym.envs.period_kernel", "drillgym.envs.sensor_kernel", "drillgym.bifurcation.flows")
_TEMPLATE_PACKAGE = "drillgym.kernels"
_BRAKE_CFGS = (1, 3)  # torsional, coupled
_CFG_CODES = {"upper": 0, "torsional": 1, "lateral": 2, "coupled": 3, "free_vibration": 4}
_JIT = 'njit(inline="always", fastmath=True, error_model="numpy")'


def cache_root() -> Path:
    """Directory of the generated kernel packages (``$DRILLGYM_KERNEL_CACHE`` or ~/.cache/drillgym/kernels)."""
    env = os.environ.get("DRILLGYM_KERNEL_CACHE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "drillgym" / "kernels"


# ---------------------------------------------------------------------------------------------
# argument resolution: an effect function's argument names -> expressions in a kernel
class _Context:
    """Expressions for the quantities of the vocabulary in one kernel variant."""

    def __init__(self, lane: bool, comp: "Composition", effect_index: int, disc: str | None = None):
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
        lane = {"theta_u": "thu", "theta_l": "thl", "omega_u": "wu", "omega_l": "wl", "x": "x", "y": "yy",
                "vx": "vx", "vy": "vy"}
        scalar = {"theta_u": "y[0]", "theta_l": "y[1]", "omega_u": "y[2]", "omega_l": "y[3]", "x": "y[4]",
                  "y": "y[5]", "vx": "y[6]", "vy": "y[7]"}
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


def _call(comp: "Composition", ctx: _Context, fn: str, chain_u: str = "u") -> str:
    eff = comp.effects[ctx.i]
    args = ", ".join(ctx.resolve(a, chain_u) for a in eff.argument_names(fn))
    return f"_e{ctx.i}_{fn}{'_v' if ctx.lane else ''}({args})"


def _fixed_frame_prologue(lane: bool) -> list[str]:
    if lane:
        return ["_st, _ct = vsincos(thu)",
                "_X = x * _ct - yy * _st", "_Y = x * _st + yy * _ct",
                "_VX = _ct * vx - _st * vy - _Y * wu", "_VY = _st * vx + _ct * vy + _X * wu"]
    return ["_ct = math.cos(y[0])", "_st = math.sin(y[0])",
            "_X = y[4] * _ct - y[5] * _st", "_Y = y[4] * _st + y[5] * _ct",
            "_VX = _ct * y[6] - _st * y[7] - _Y * y[2]", "_VY = _st * y[6] + _ct * y[7] + _X * y[2]"]


def _prologue(lane: bool, fixed_needed: bool, *more: str) -> list[str]:
    """The first lines of a hook: the fixed-frame quantities when an effect reads them, the brake flag,
    then ``more``."""
    return (_fixed_frame_prologue(lane) if fixed_needed else []) + ["brake = 1.0 if (cfg == 1 or cfg == 3) else 0.0",
                                                                   *more]


def _cfg_guard(eff: type[Effect]) -> str | None:
    cfgs = [_CFG_CODES[c] for c in eff.configurations]
    if len(cfgs) == len(_CFG_CODES):
        return None
    return " or ".join(f"cfg == {c}" for c in cfgs) if cfgs else "False"


def switch_rows(comp: "Composition") -> dict[int, int]:
    """Effect index -> row of its switch in the lane parameter matrix (after the parameter rows), for
    the effects that declare where they vanish (:meth:`Effect.neutral_values`)."""
    out: dict[int, int] = {}
    for i, eff in enumerate(comp.effects):
        if eff.neutral_values() is not None:
            out[i] = comp.n_params + len(out)
    return out


def _switch(comp: "Composition", lane: bool, i: int) -> str | None:
    """The condition under which effect i runs (None: always); skipping is exact because the effect
    adds nothing at its neutral values.  Scalar kernels test the run's own parameters; lane kernels
    read the batch's switch (on when any lane's parameters leave the neutral values), so the branch
    is the same in every lane and the loops stay vectorised."""
    row = switch_rows(comp).get(i)
    if row is None:
        return None
    if lane:
        return f"PT[{row}, 0] != 0.0"
    return " or ".join(f"p[{comp.param_index(n)}] != {v!r}" for n, v in comp.effects[i].neutral_values().items())


def _both(*conds: str | None) -> str | None:
    conds = tuple(c for c in conds if c)
    if not conds:
        return None
    return conds[0] if len(conds) == 1 else " and ".join(f"({c})" for c in conds)


def _lane_params(comp: "Composition") -> str:
    """hk_lane_params(P): the lane parameter matrix PT (N_PARAMS + N_SWITCHES, B), the parameter rows
    transposed, then one switch row per skippable effect (1.0 in every lane when any lane needs it)."""
    rows = switch_rows(comp)
    lines = [f"@{_JIT}", "def hk_lane_params(P):", "    B = P.shape[0]",
             "    PT = np.empty((N_PARAMS + N_SWITCHES, B))",
             "    for j in range(N_PARAMS):", "        for k in range(B):", "            PT[j, k] = P[k, j]"]
    for i, row in rows.items():
        eff = comp.effects[i]
        test = " or ".join(f"P[k, {comp.param_index(n)}] != {v!r}" for n, v in eff.neutral_values().items())
        lines += [f"    on = 0.0", "    for k in range(B):", f"        if {test}:", "            on = 1.0",
                  f"    for k in range(B):", f"        PT[{row}, k] = on  # {eff.name}"]
    lines.append("    return PT")
    return "\n".join(lines) + "\n"


def _rhs(comp: "Composition", lane: bool) -> str:
    """hk_rhs (scalar: input chain, forces, state derivatives) or hk_states_lane (lane: the effects'
    state derivatives into K, called in a loop of its own; the lane kernel's forces and input chain are
    :func:`_effects_lane`'s)."""
    body: list[str] = []
    fixed_needed = False
    dst = (lambda j: f"K[nm + {j}, k]") if lane else (lambda j: f"dy[{8 + j}]")
    want_forces = not lane

    def emit(lines: list[str], guard: str | None, zero_states: list[int]) -> None:
        if guard is None:
            body.extend(lines)
            return
        body.append(f"if {guard}:")
        body.extend("    " + ln for ln in lines)
        if lane and zero_states:
            body.append("else:")
            body.extend(f"    {dst(j)} = 0.0" for j in zero_states)

    def state_lines(i: int, ctx: _Context, chain_u: str) -> tuple[list[str], list[int]]:
        eff = comp.effects[i]
        if not eff.states:
            return [], []
        idx = [comp.state_index(s.name) for s in eff.states]
        call = _call(comp, ctx, "derivative", chain_u)
        if len(idx) == 1:
            return [f"{dst(idx[0])} = {call}"], idx
        lines = [f"_d{i} = {call}"] + [f"{dst(j)} = _d{i}[{n}]" for n, j in enumerate(idx)]
        return lines, idx

    # 1. the input chain, in order (a Delay acts on the command before this hook)
    for i, eff in enumerate(comp.effects):
        if not issubclass(eff, Input):
            continue
        ctx = _Context(lane, comp, i)
        lines, idx = state_lines(i, ctx, "u")
        lines.append(f"u = {_call(comp, ctx, 'voltage', 'u')}")
        fixed_needed |= ctx.needs_fixed
        emit(lines, _both(_cfg_guard(eff), _switch(comp, lane, i)), idx)
    # 2. forces and the other effects' states ('u' = the voltage at the motor)
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Input):
            continue
        ctx = _Context(lane, comp, i)
        lines, idx = state_lines(i, ctx, "u")
        if issubclass(eff, Force) and want_forces:
            if eff.acts_on == "lateral":
                lines += [f"_f{i} = {_call(comp, ctx, 'force')}", f"_QX += _f{i}[0]", f"_QY += _f{i}[1]"]
            else:
                target = {"upper": "_Qu", "lower": "_Ql", "string": "_Qs"}[eff.acts_on]
                lines.append(f"{target} += {_call(comp, ctx, 'torque')}")
        fixed_needed |= ctx.needs_fixed
        if lines:
            emit(lines, _both(_cfg_guard(eff), _switch(comp, lane, i)), idx)
    has_lateral = want_forces and any(issubclass(e, Force) and e.acts_on == "lateral" for e in comp.effects)
    if has_lateral:
        fixed_needed = True
        tail = ["if cfg == 2 or cfg == 3:",
                "    _Qu += -_QX * _Y + _QY * _X",
                "    _Qx = _QX * _ct + _QY * _st",
                "    _Qy = -_QX * _st + _QY * _ct",
                "else:",
                "    _Qx = 0.0",
                "    _Qy = 0.0"]
    else:
        tail = ["_Qx = 0.0", "_Qy = 0.0"]
    pro = _prologue(lane, fixed_needed, "_Qu = 0.0", "_Ql = 0.0", "_Qs = 0.0", "_QX = 0.0", "_QY = 0.0")
    if lane:
        sig = "hk_states_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, K)"
        ret = "    return 0"
        tail = []
    else:
        sig = "hk_rhs(t, u, y, p, cfg, dy)"
        ret = "    return u, _Qu, _Ql, _Qs, _Qx, _Qy"
    lines = [f"@{_JIT}", f"def {sig}:"]
    lines += ["    " + ln for ln in pro + body + tail]
    lines.append(ret)
    return "\n".join(lines) + "\n"


#: rows of the lane effects' work array E (hk_effects_lane)
EFFECT_ROWS = ("volt", "Qu", "Ql", "Qs", "Qx", "Qy", "tfu", "tfl", "gu", "gl")


def _lane_loop(lines: list[str], fixed: bool, disc: str | None = None) -> list[str]:
    """``for k in range(n):`` over the lanes, with the lane's quantities the effect may name."""
    pro = ["t = TT[k] + tc", "thu = thu_[k]", "thl = thl_[k]", "wu = wu_[k]", "wl = wl_[k]", "x = x_[k]",
           "yy = y_[k]", "vx = vx_[k]", "vy = vy_[k]", "u = VOLT[k]"]
    if fixed:
        pro += _fixed_frame_prologue(True)
    if disc is not None:
        m, w, tf = ("MU", "wu", "TFU") if disc == "upper" else ("ML", "wl", "TFL")
        pro += [f"d = {m}[k]", f"aw = abs({w})", f"T = {tf}[k]"]
    return ["for k in range(n):"] + ["    " + ln for ln in pro + lines]


def _effects_lane(comp: "Composition") -> str:
    """hk_effects_lane: every effect on every lane, one loop per effect, its switch and configuration
    guard *outside* the loop: an effect switched off costs nothing, and each loop is small enough for
    LLVM to vectorise (one loop holding every effect of a large composition ran scalar, 3x slower).
    In: the lane rows and, in E[6:8], the base friction laws' slip torques.  Out: E[0] the voltage at
    the motor (V), E[1:4] Qu, Ql, Qs (N m), E[4:6] Qx, Qy (N, rotating frame), E[6:8] the slip torques
    with the friction effects (0 for a stuck disc)."""
    body = ["n = thu_.shape[0]", ", ".join(n.upper() for n in EFFECT_ROWS) + " = " +
            ", ".join(f"E[{i}]" for i in range(len(EFFECT_ROWS))),
            "for k in range(n):", "    VOLT[k] = U[k]"]
    body += [f"    {r}[k] = 0.0" for r in ("QU", "QL", "QS", "QX", "QY")] + ["    GU[k] = 1.0", "    GL[k] = 1.0"]

    def add(i: int, lines: list[str], ctx: _Context, disc: str | None = None, cfg: bool = True) -> None:
        body.append(f"# {comp.effects[i].name}")
        guard = _both(_cfg_guard(comp.effects[i]) if cfg else None, _switch(comp, True, i))
        body.extend(_guarded(_lane_loop(lines, ctx.needs_fixed, disc), guard))

    for i, eff in enumerate(comp.effects):  # 1. the input chain, in order
        if issubclass(eff, Input):
            ctx = _Context(True, comp, i)
            add(i, [f"VOLT[k] = {_call(comp, ctx, 'voltage', 'u')}"], ctx)
    lateral = False
    for i, eff in enumerate(comp.effects):  # 2. forces ('u' = the voltage at the motor)
        if not issubclass(eff, Force):
            continue
        ctx = _Context(True, comp, i)
        if eff.acts_on == "lateral":
            lateral = True
            add(i, [f"_f = {_call(comp, ctx, 'force')}", "QX[k] += _f[0]", "QY[k] += _f[1]"], ctx)
        else:
            target = {"upper": "QU", "lower": "QL", "string": "QS"}[eff.acts_on]
            add(i, [f"{target}[k] += {_call(comp, ctx, 'torque')}"], ctx)
    if lateral:  # the fixed-frame forces' moment on the upper disc, and the forces in the rotating frame
        turn = ["_qx = QX[k]", "_qy = QY[k]", "QU[k] += -_qx * _Y + _qy * _X", "QX[k] = _qx * _ct + _qy * _st",
                "QY[k] = -_qx * _st + _qy * _ct"]
        switches = [_switch(comp, True, i) for i, e in enumerate(comp.effects)
                    if issubclass(e, Force) and e.acts_on == "lateral"]
        any_on = None if None in switches else " or ".join(switches)
        body.extend(_guarded(_lane_loop(turn, True), _both("cfg == 2 or cfg == 3", any_on)))
    for disc, tf, g in (("upper", "TFU", "GU"), ("lower", "TFL", "GL")):  # 3. friction, in order
        for i, eff in enumerate(comp.effects):
            if not (issubclass(eff, Friction) and eff.disc == disc):
                continue
            ctx = _Context(True, comp, i, disc)
            fns = eff.defined_functions()
            lines = ([f"{tf}[k] = {_call(comp, ctx, 'slip')}"] if "slip" in fns else []) + \
                    ([f"{g}[k] = {g}[k] * {_call(comp, ctx, 'level')}"] if "level" in fns else [])
            if lines:
                add(i, lines, ctx, disc, cfg=False)
    body += ["for k in range(n):",  # levels last (as the scalar hooks); a stuck disc has no slip torque
             "    TFU[k] = GU[k] * TFU[k] if MU[k] != 0.0 else 0.0",
             "    TFL[k] = GL[k] * TFL[k] if ML[k] != 0.0 else 0.0"]
    sig = "hk_effects_lane(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E)"
    return "\n".join([f"@{_JIT}", f"def {sig}:"] + ["    " + ln for ln in body] + ["    return 0"]) + "\n"


def _input_chain(comp: "Composition", lane: bool):
    """(index, effect, context) of the Input effects, in the order the command passes through them."""
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Input):
            yield i, eff, _Context(lane, comp, i)


def _lag(comp: "Composition", lane: bool) -> str:
    """hk_lag / hk_lag_lane: the declared first-order lag states (``Input.lag``) at h after the step
    start, exactly: s(h) = v + (s0 - v) exp(-h / tau), v the voltage entering the effect at the
    step start (the input chain evaluated at the start state y / Y, held over the step)."""
    body: list[str] = []
    fixed_needed = False
    for i, eff, ctx in _input_chain(comp, lane):
        lines = []
        frozen = []
        for st, tau in (getattr(eff, "lag", None) or {}).items():
            j = comp.state_index(st)
            q = comp.param_index(tau)
            if lane:
                lines.append(f"Yo[nm + {j}, k] = u + (Y[nm + {j}, k] - u) * vexp(-h / PT[{q}, k])")
                frozen.append(f"Yo[nm + {j}, k] = Y[nm + {j}, k]")
            else:
                lines.append(f"yo[{8 + j}] = u + (y[{8 + j}] - u) * math.exp(-h / p[{q}])")
                frozen.append(f"yo[{8 + j}] = y[{8 + j}]")
        lines.append(f"u = {_call(comp, ctx, 'voltage', 'u')}")
        fixed_needed |= ctx.needs_fixed
        guard = _both(_cfg_guard(eff), _switch(comp, lane, i))
        if guard is None:
            body.extend(lines)
        else:
            body.append(f"if {guard}:")
            body.extend("    " + ln for ln in lines)
            if frozen:
                body.append("else:")
                body.extend("    " + ln for ln in frozen)
    pro = _prologue(lane, fixed_needed)
    if lane:
        sig = "hk_lag_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, h, Yo)"
    else:
        sig = "hk_lag(t, u, y, p, cfg, h, yo)"
    lines = [f"@{_JIT}", f"def {sig}:"] + ["    " + ln for ln in pro + body] + ["    return 0"]
    return "\n".join(lines) + "\n"


def _lag_start(comp: "Composition") -> str:
    """hk_lag_start(t, u, y, p, cfg): the lag states not given at the start (NaN) set to the steady
    state of the first command held before the start, the same history the delay lines assume: each
    lag state equals the voltage entering it (the input chain evaluated up to that effect)."""
    body: list[str] = []
    fixed_needed = False
    for i, eff, ctx in _input_chain(comp, False):
        for st in (getattr(eff, "lag", None) or {}):
            j = comp.state_index(st)
            body += [f"if y[{8 + j}] != y[{8 + j}]:", f"    y[{8 + j}] = u"]
        call = [f"u = {_call(comp, ctx, 'voltage', 'u')}"]
        fixed_needed |= ctx.needs_fixed
        body += _guarded(call, _both(_cfg_guard(eff), _switch(comp, False, i)))
    pro = _prologue(False, fixed_needed)
    lines = [f"@{_JIT}", "def hk_lag_start(t, u, y, p, cfg):"] + ["    " + ln for ln in pro + body] + ["    return 0"]
    return "\n".join(lines) + "\n"


def _guarded(lines: list[str], cond: str | None) -> list[str]:
    if cond is None or not lines:
        return lines
    return [f"if {cond}:"] + ["    " + ln for ln in lines]


def _friction(comp: "Composition", lane: bool, disc: str, what: str) -> str:
    """hk_slip_* / hk_bounds_* (scalar or lane) for one disc."""
    sfx = "u" if disc == "upper" else "l"
    mech = "k, t, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, brake" if lane else "t, y, p, brake"
    body: list[str] = []
    levels: list[str] = []
    fixed_needed = False
    for i, eff in enumerate(comp.effects):
        if not (issubclass(eff, Friction) and eff.disc == disc):
            continue
        ctx = _Context(lane, comp, i, disc)
        fns = eff.defined_functions()
        sw = _switch(comp, lane, i)
        chosen = []
        if what == "slip" and "slip" in fns:
            chosen.append(f"T = {_call(comp, ctx, 'slip')}")
        if what == "bounds" and "stick" in fns:
            chosen.append(f"lo, hi = {_call(comp, ctx, 'stick')}")
        body.extend(_guarded(chosen, sw))
        if "level" in fns:
            levels.append((_call(comp, ctx, "level"), sw))
        fixed_needed |= ctx.needs_fixed
    if levels and not any(sw for _, sw in levels):
        body.append("_g = " + " * ".join(c for c, _ in levels))
    elif levels:  # a skipped level is a factor of 1
        body.append("_g = 1.0")
        for c, sw in levels:
            body.extend(_guarded([f"_g = _g * {c}"], sw))
    pro = _fixed_frame_prologue(lane) if fixed_needed else []
    if what == "slip":
        sig = f"hk_slip_{sfx}{'_lane' if lane else ''}(T, d, aw, {mech})"
        ret = "_g * T" if levels else "T"
    else:
        sig = f"hk_bounds_{sfx}{'_lane' if lane else ''}(lo, hi, {mech})"
        ret = "_g * lo, _g * hi" if levels else "lo, hi"
    lines = [f"@{_JIT}", f"def {sig}:"] + ["    " + ln for ln in pro + body] + [f"    return {ret}"]
    return "\n".join(lines) + "\n"


def _delay(comp: "Composition") -> str:
    terms = []
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Delay):
            terms.append(_call(comp, _Context(False, comp, i), "delay"))
    return f"@{_JIT}\ndef hk_delay(p):\n    return {' + '.join(terms) if terms else '0.0'}\n"


def _measure(comp: "Composition") -> str:
    lines = [f"@{_JIT}", "def hk_measure(theta_u, theta_l, X, Y, p):"]
    for i, eff in enumerate(comp.effects):
        if not issubclass(eff, Measurement):
            continue
        args = []
        own = {p.name: comp.param_index(p.name) for p in eff.parameters}
        for a in eff.argument_names("measure"):
            if a in own:
                args.append(f"p[{own[a]}]")
            elif a in IDX.__dict__:
                args.append(f"p[{getattr(IDX, a)}]")
            else:
                args.append(a)  # a channel
        call = f"_e{i}_measure({', '.join(args)})"
        ch = ", ".join(eff.channels)
        lines.append(f"    {ch}{',' if len(eff.channels) == 1 else ''} = {call}" if len(eff.channels) > 1
                     else f"    {ch} = {call}")
    lines.append("    return theta_u, theta_l, X, Y")
    lines += ["", "", "@njit(cache=True)", "def measure_arrays(TU, TL, X, Y, p):",
              "    n = TU.shape[0]", "    out = np.empty((4, n))", "    for i in range(n):",
              "        a, b, c, d = hk_measure(TU[i], TL[i], X[i], Y[i], p)",
              "        out[0, i] = a", "        out[1, i] = b", "        out[2, i] = c", "        out[3, i] = d",
              "    return out"]
    return "\n".join(lines) + "\n"


def _effect_imports(comp: "Composition") -> list[str]:
    lines = []
    for i, eff in enumerate(comp.effects):
        origin = getattr(eff, "__drillgym_file__", None)
        if origin:
            lines.append(f"_E{i} = _load_class({str(origin)!r}, {eff.__qualname__!r})")
        else:
            lines.append(f"from {eff.__module__} import {eff.__qualname__} as _E{i}")
        for fn in eff.defined_functions():
            lines.append(f"_e{i}_{fn} = {_JIT}(_function(_E{i}, {fn!r}))")
            lines.append(f"_e{i}_{fn}_v = {_JIT}(_simd(_function(_E{i}, {fn!r})))  # lane variant")
    return lines


def hooks_source(comp: "Composition") -> str:
    """The generated hooks module of a composition (Python source)."""
    parts = [
        f'"""Generated by drillgym.effects.codegen for the composition {comp.label!r}.  Do not edit."""',
        "",
        "import math",
        "",
        "import numpy as np",
        "from numba import njit",
        "",
        "from drillgym.effects.registry import effect_function as _function, load_class_from_file as _load_class",
        "from drillgym.effects.simd import simd_variant as _simd",
        "from drillgym.vmath import vexp, vsincos",
        "",
        *_effect_imports(comp),
        "",
        f"N_EFFECT_STATES = {comp.n_states}",
        f"N_STATE = {8 + comp.n_states}",
        f"N_OUT = {len(comp.output_names)}",
        f"HAS_DELAY = {any(issubclass(e, Delay) for e in comp.effects)}",
        f"HAS_LATERAL_FORCE = {any(issubclass(e, Force) and e.acts_on == 'lateral' for e in comp.effects)}",
        f"N_PARAMS = {comp.n_params}",
        f"N_SWITCHES = {len(switch_rows(comp))}",
        f"HAS_LAG = {any(issubclass(e, Input) and bool(getattr(e, 'lag', None)) for e in comp.effects)}",
        f"HAS_LANE_EFFECTS = {any(issubclass(e, (Input, Force, Friction)) for e in comp.effects)}",
        "",
        "",
        _lane_params(comp), "",
        _rhs(comp, False), "",
        _effects_lane(comp), "",
        _rhs(comp, True), "",
        _lag(comp, False), "",
        _lag(comp, True), "",
        _lag_start(comp), "",
    ]
    for disc in ("upper", "lower"):
        for what in ("slip", "bounds"):
            parts += [_friction(comp, False, disc, what), ""]
        parts += [_friction(comp, True, disc, "bounds"), ""]
    parts += [_delay(comp), "", _measure(comp)]
    return "\n".join(parts)


# ---------------------------------------------------------------------------------------------
# specialised packages on disk
@lru_cache(maxsize=1)
def _environment_digest() -> str:
    h = hashlib.sha256()
    roots = [f"{_TEMPLATE_PACKAGE}.{name}" for name in (*CORE_TEMPLATES, "hooks")] + list(CLIENT_TEMPLATES)
    # the generated hooks import these (see hooks_source), and the code generator writes the hooks
    roots += ["drillgym.effects.registry", "drillgym.effects.simd", "drillgym.effects.library",
              "drillgym.effects.codegen", "drillgym.vmath"]
    h.update(modules_digest(roots).encode())
    h.update(numba.__version__.encode())
    h.update(sys.version.encode())
    return h.hexdigest()


def _template_source(module: str) -> str:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ImportError(f"kernel template {module} not found")
    return Path(spec.origin).read_text(encoding="utf-8")


def _specialise(source: str, package: str) -> str:
    """A template's source importing the composition's package instead of drillgym.kernels."""
    return source.replace(f"from {_TEMPLATE_PACKAGE}.", f"from {package}.")


def package_name(comp: "Composition", hooks: str) -> str:
    h = hashlib.sha256()
    h.update(_environment_digest().encode())
    h.update(hooks.encode())
    for eff in comp.effects:
        origin = getattr(eff, "__drillgym_file__", None)
        if not origin and not eff.__module__.startswith("drillgym."):  # e.g. an entry-point effect
            module = sys.modules.get(eff.__module__)
            origin = getattr(module, "__file__", None)
        if origin:
            h.update(Path(origin).read_bytes())
    return "_dgk_" + h.hexdigest()[:24]


def _ensure_on_path(root: Path) -> None:
    s = str(root)
    if s not in sys.path:
        sys.path.insert(0, s)


STALE_AFTER_S = 3600.0  # packages built from other drillgym sources are removed after an hour unused


def prune_stale(root: Path) -> int:
    """Remove generated packages built from other drillgym sources (never loaded again: the package
    name hashes the sources) once they have not been touched for an hour; returns how many."""
    digest = _environment_digest()
    removed = 0
    now = time.time()
    for d in root.glob("_dgk_*"):
        try:
            meta = (d / "ENVIRONMENT").read_text().strip()
            if meta != digest and now - d.stat().st_mtime > STALE_AFTER_S:
                shutil.rmtree(d, ignore_errors=True)
                removed += 1
        except OSError:
            continue
    return removed


def _write_package(root: Path, package: str, hooks: str, label: str) -> Path:
    final = root / package
    if final.exists():
        return final
    root.mkdir(parents=True, exist_ok=True)
    prune_stale(root)
    tmp = Path(tempfile.mkdtemp(prefix=f".{package}-", dir=root))
    try:
        (tmp / "ENVIRONMENT").write_text(_environment_digest() + "\n")
        (tmp / "__init__.py").write_text(f'"""drillgym kernels for the composition {label!r} (generated)."""\n')
        (tmp / "hooks.py").write_text(hooks)
        for name in CORE_TEMPLATES:
            (tmp / f"{name}.py").write_text(_specialise(_template_source(f"{_TEMPLATE_PACKAGE}.{name}"), package))
        try:
            os.rename(tmp, final)
        except OSError:  # another process wrote it first
            shutil.rmtree(tmp, ignore_errors=True)
    finally:
        if tmp.exists() and final.exists() and tmp != final:
            shutil.rmtree(tmp, ignore_errors=True)
    return final


def build_kernels(comp: "Composition") -> "CompiledModel":
    """The specialised kernel modules of a composition (written once, then loaded from the cache)."""
    hooks = hooks_source(comp)
    package = package_name(comp, hooks)
    root = cache_root()
    _write_package(root, package, hooks, comp.label)
    _ensure_on_path(root)
    importlib.invalidate_caches()
    return CompiledModel(package, root)


def _load_compiled_model(package: str, root: str, clients: tuple = ()) -> "CompiledModel":
    _ensure_on_path(Path(root))
    model = CompiledModel(package, Path(root))
    for c in clients:
        model.client(c)
    return model


class CompiledModel:
    """The kernels of one composition: attributes ``model``, ``stepping``, ``lanes``, ``hooks``
    (modules) and :meth:`client` for specialised client templates."""

    def __init__(self, package: str, root: Path) -> None:
        self.package = package
        self.root = root
        self.hooks = importlib.import_module(f"{package}.hooks")
        self.model = importlib.import_module(f"{package}.model")
        self.stepping = importlib.import_module(f"{package}.stepping")
        self.lanes = importlib.import_module(f"{package}.lanes")
        self._clients: dict[str, ModuleType] = {}

    @property
    def path(self) -> Path:
        return self.root / self.package

    def __reduce__(self):  # modules do not pickle: rebuild from the package (written on disk)
        return (_load_compiled_model, (self.package, str(self.root), tuple(self._clients)))

    def client(self, module: str) -> ModuleType:
        """A specialised copy of a client template (a drillgym module whose compiled code calls the
        kernels, e.g. ``drillgym.bifurcation.flows``): its ``drillgym.kernels.*`` imports point
        to this composition."""
        if module not in self._clients:
            name = "client_" + module.replace(".", "_")
            target = self.path / f"{name}.py"
            if not target.exists():
                text = _specialise(_template_source(module), self.package)
                fd, tmp = tempfile.mkstemp(prefix=f".{name}-", suffix=".py", dir=self.path)
                with os.fdopen(fd, "w", encoding="utf-8") as f:
                    f.write(text)
                os.replace(tmp, target)
                importlib.invalidate_caches()
            self._clients[module] = importlib.import_module(f"{self.package}.{name}")
        return self._clients[module]
