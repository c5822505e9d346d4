"""Writing the hooks of a composition, part 2: the hooks module's source.

For a composition (an ordered tuple of effect classes) :func:`hooks_source` writes the hooks of
:mod:`drillgym.kernels.hooks` as Python source in which every effect function is called with the
arguments its names ask for (:mod:`drillgym.effects.hook_context`): the input chain, forces and
state derivatives (scalar and lane variants), the exact lag states, the friction effects' slip
torques and stick bounds, the delays and the measurements.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..params import IDX
from .base import Delay, Force, Friction, Input, Measurement
from .hook_context import (
    JIT,
    HookContext,
    both,
    call_effect,
    cfg_guard,
    fixed_frame_prologue,
    guarded,
    prologue,
    switch_condition,
    switch_rows,
)

if TYPE_CHECKING:  # pragma: no cover
    from .composition import Composition

__all__ = ["hooks_source", "EFFECT_ROWS", "effect_file_copy"]


def _lane_params(comp: Composition) -> str:
    """hk_lane_params(P): the lane parameter matrix PT (N_PARAMS + N_SWITCHES, B), the parameter rows
    transposed, then one switch row per skippable effect (1.0 in every lane when any lane needs it)."""
    rows = switch_rows(comp)
    lines = [
        f"@{JIT}",
        "def hk_lane_params(P):",
        "    B = P.shape[0]",
        "    PT = np.empty((N_PARAMS + N_SWITCHES, B))",
        "    for j in range(N_PARAMS):",
        "        for k in range(B):",
        "            PT[j, k] = P[k, j]",
    ]
    for i, row in rows.items():
        eff = comp.effects[i]
        test = " or ".join(f"P[k, {comp.param_index(n)}] != {v!r}" for n, v in eff.neutral_values().items())
        lines += [
            "    on = 0.0",
            "    for k in range(B):",
            f"        if {test}:",
            "            on = 1.0",
            "    for k in range(B):",
            f"        PT[{row}, k] = on  # {eff.name}",
        ]
    lines.append("    return PT")
    return "\n".join(lines) + "\n"


def _rhs(comp: Composition, lane: bool) -> str:
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

    def state_lines(i: int, ctx: HookContext, chain_u: str) -> tuple[list[str], list[int]]:
        eff = comp.effects[i]
        if not eff.states:
            return [], []
        idx = [comp.state_index(s.name) for s in eff.states]
        call = call_effect(comp, ctx, "derivative", chain_u)
        if len(idx) == 1:
            return [f"{dst(idx[0])} = {call}"], idx
        lines = [f"_d{i} = {call}"] + [f"{dst(j)} = _d{i}[{n}]" for n, j in enumerate(idx)]
        return lines, idx

    # 1. the input chain, in order (a Delay acts on the command before this hook)
    for i, eff in enumerate(comp.effects):
        if not issubclass(eff, Input):
            continue
        ctx = HookContext(lane, comp, i)
        lines, idx = state_lines(i, ctx, "u")
        lines.append(f"u = {call_effect(comp, ctx, 'voltage', 'u')}")
        fixed_needed |= ctx.needs_fixed
        emit(lines, both(cfg_guard(eff), switch_condition(comp, lane, i)), idx)
    # 2. forces and the other effects' states ('u' = the voltage at the motor)
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Input):
            continue
        ctx = HookContext(lane, comp, i)
        lines, idx = state_lines(i, ctx, "u")
        if issubclass(eff, Force) and want_forces:
            if eff.acts_on == "lateral":
                lines += [f"_f{i} = {call_effect(comp, ctx, 'force')}", f"_QX += _f{i}[0]", f"_QY += _f{i}[1]"]
            else:
                target = {"upper": "_Qu", "lower": "_Ql", "string": "_Qs"}[eff.acts_on]
                lines.append(f"{target} += {call_effect(comp, ctx, 'torque')}")
        fixed_needed |= ctx.needs_fixed
        if lines:
            emit(lines, both(cfg_guard(eff), switch_condition(comp, lane, i)), idx)
    has_lateral = want_forces and any(issubclass(e, Force) and e.acts_on == "lateral" for e in comp.effects)
    if has_lateral:
        fixed_needed = True
        tail = [
            "if cfg == 2 or cfg == 3:",
            "    _Qu += -_QX * _Y + _QY * _X",
            "    _Qx = _QX * _ct + _QY * _st",
            "    _Qy = -_QX * _st + _QY * _ct",
            "else:",
            "    _Qx = 0.0",
            "    _Qy = 0.0",
        ]
    else:
        tail = ["_Qx = 0.0", "_Qy = 0.0"]
    pro = prologue(lane, fixed_needed, "_Qu = 0.0", "_Ql = 0.0", "_Qs = 0.0", "_QX = 0.0", "_QY = 0.0")
    if lane:
        sig = "hk_states_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, K)"
        ret = "    return 0"
        tail = []
    else:
        sig = "hk_rhs(t, u, y, p, cfg, dy)"
        ret = "    return u, _Qu, _Ql, _Qs, _Qx, _Qy"
    lines = [f"@{JIT}", f"def {sig}:"]
    lines += ["    " + ln for ln in pro + body + tail]
    lines.append(ret)
    return "\n".join(lines) + "\n"


#: rows of the lane effects' work array E (hk_effects_lane)
EFFECT_ROWS = ("volt", "Qu", "Ql", "Qs", "Qx", "Qy", "tfu", "tfl", "gu", "gl")


def _lane_loop(lines: list[str], fixed: bool, disc: str | None = None) -> list[str]:
    """``for k in range(n):`` over the lanes, with the lane's quantities the effect may name."""
    pro = [
        "t = TT[k] + tc",
        "thu = thu_[k]",
        "thl = thl_[k]",
        "wu = wu_[k]",
        "wl = wl_[k]",
        "x = x_[k]",
        "yy = y_[k]",
        "vx = vx_[k]",
        "vy = vy_[k]",
        "u = VOLT[k]",
    ]
    if fixed:
        pro += fixed_frame_prologue(True)
    if disc is not None:
        m, w, tf = ("MU", "wu", "TFU") if disc == "upper" else ("ML", "wl", "TFL")
        pro += [f"d = {m}[k]", f"aw = abs({w})", f"T = {tf}[k]"]
    return ["for k in range(n):"] + ["    " + ln for ln in pro + lines]


def _effects_lane(comp: Composition) -> str:
    """hk_effects_lane: every effect on every lane, one loop per effect, its switch and configuration
    guard *outside* the loop: an effect switched off costs nothing, and each loop is small enough for
    LLVM to vectorise (one loop holding every effect of a large composition ran scalar, 3x slower).
    In: the lane rows and, in E[6:8], the base friction laws' slip torques.  Out: E[0] the voltage at
    the motor (V), E[1:4] Qu, Ql, Qs (N m), E[4:6] Qx, Qy (N, rotating frame), E[6:8] the slip torques
    with the friction effects (0 for a stuck disc)."""
    body = [
        "n = thu_.shape[0]",
        ", ".join(n.upper() for n in EFFECT_ROWS) + " = " + ", ".join(f"E[{i}]" for i in range(len(EFFECT_ROWS))),
        "for k in range(n):",
        "    VOLT[k] = U[k]",
    ]
    body += [f"    {r}[k] = 0.0" for r in ("QU", "QL", "QS", "QX", "QY")] + ["    GU[k] = 1.0", "    GL[k] = 1.0"]

    def add(i: int, lines: list[str], ctx: HookContext, disc: str | None = None, cfg: bool = True) -> None:
        body.append(f"# {comp.effects[i].name}")
        guard = both(cfg_guard(comp.effects[i]) if cfg else None, switch_condition(comp, True, i))
        body.extend(guarded(_lane_loop(lines, ctx.needs_fixed, disc), guard))

    for i, eff in enumerate(comp.effects):  # 1. the input chain, in order
        if issubclass(eff, Input):
            ctx = HookContext(True, comp, i)
            add(i, [f"VOLT[k] = {call_effect(comp, ctx, 'voltage', 'u')}"], ctx)
    lateral = False
    for i, eff in enumerate(comp.effects):  # 2. forces ('u' = the voltage at the motor)
        if not issubclass(eff, Force):
            continue
        ctx = HookContext(True, comp, i)
        if eff.acts_on == "lateral":
            lateral = True
            add(i, [f"_f = {call_effect(comp, ctx, 'force')}", "QX[k] += _f[0]", "QY[k] += _f[1]"], ctx)
        else:
            target = {"upper": "QU", "lower": "QL", "string": "QS"}[eff.acts_on]
            add(i, [f"{target}[k] += {call_effect(comp, ctx, 'torque')}"], ctx)
    if lateral:  # the fixed-frame forces' moment on the upper disc, and the forces in the rotating frame
        turn = [
            "_qx = QX[k]",
            "_qy = QY[k]",
            "QU[k] += -_qx * _Y + _qy * _X",
            "QX[k] = _qx * _ct + _qy * _st",
            "QY[k] = -_qx * _st + _qy * _ct",
        ]
        switches = [
            switch_condition(comp, True, i)
            for i, e in enumerate(comp.effects)
            if issubclass(e, Force) and e.acts_on == "lateral"
        ]
        any_on = None if None in switches else " or ".join(switches)
        body.extend(guarded(_lane_loop(turn, True), both("cfg == 2 or cfg == 3", any_on)))
    for disc, tf, g in (("upper", "TFU", "GU"), ("lower", "TFL", "GL")):  # 3. friction, in order
        for i, eff in enumerate(comp.effects):
            if not (issubclass(eff, Friction) and eff.disc == disc):
                continue
            ctx = HookContext(True, comp, i, disc)
            fns = eff.defined_functions()
            lines = ([f"{tf}[k] = {call_effect(comp, ctx, 'slip')}"] if "slip" in fns else []) + (
                [f"{g}[k] = {g}[k] * {call_effect(comp, ctx, 'level')}"] if "level" in fns else []
            )
            if lines:
                add(i, lines, ctx, disc, cfg=False)
    body += [
        "for k in range(n):",  # levels last (as the scalar hooks); a stuck disc has no slip torque
        "    TFU[k] = GU[k] * TFU[k] if MU[k] != 0.0 else 0.0",
        "    TFL[k] = GL[k] * TFL[k] if ML[k] != 0.0 else 0.0",
    ]
    sig = "hk_effects_lane(thu_, thl_, wu_, wl_, x_, y_, vx_, vy_, Y, nm, MU, ML, U, PT, TT, tc, cfg, brake, E)"
    return "\n".join([f"@{JIT}", f"def {sig}:"] + ["    " + ln for ln in body] + ["    return 0"]) + "\n"


def _input_chain(comp: Composition, lane: bool):
    """(index, effect, context) of the Input effects, in the order the command passes through them."""
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Input):
            yield i, eff, HookContext(lane, comp, i)


def _lag(comp: Composition, lane: bool) -> str:
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
        lines.append(f"u = {call_effect(comp, ctx, 'voltage', 'u')}")
        fixed_needed |= ctx.needs_fixed
        guard = both(cfg_guard(eff), switch_condition(comp, lane, i))
        if guard is None:
            body.extend(lines)
        else:
            body.append(f"if {guard}:")
            body.extend("    " + ln for ln in lines)
            if frozen:
                body.append("else:")
                body.extend("    " + ln for ln in frozen)
    pro = prologue(lane, fixed_needed)
    if lane:
        sig = "hk_lag_lane(k, t, u, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, cfg, h, Yo)"
    else:
        sig = "hk_lag(t, u, y, p, cfg, h, yo)"
    lines = [f"@{JIT}", f"def {sig}:"] + ["    " + ln for ln in pro + body] + ["    return 0"]
    return "\n".join(lines) + "\n"


def _lag_start(comp: Composition) -> str:
    """hk_lag_start(t, u, y, p, cfg): the lag states not given at the start (NaN) set to the steady
    state of the first command held before the start, the same history the delay lines assume: each
    lag state equals the voltage entering it (the input chain evaluated up to that effect)."""
    body: list[str] = []
    fixed_needed = False
    for i, eff, ctx in _input_chain(comp, False):
        for st in getattr(eff, "lag", None) or {}:
            j = comp.state_index(st)
            body += [f"if y[{8 + j}] != y[{8 + j}]:", f"    y[{8 + j}] = u"]
        call = [f"u = {call_effect(comp, ctx, 'voltage', 'u')}"]
        fixed_needed |= ctx.needs_fixed
        body += guarded(call, both(cfg_guard(eff), switch_condition(comp, False, i)))
    pro = prologue(False, fixed_needed)
    lines = [f"@{JIT}", "def hk_lag_start(t, u, y, p, cfg):"] + ["    " + ln for ln in pro + body] + ["    return 0"]
    return "\n".join(lines) + "\n"


def _friction(comp: Composition, lane: bool, disc: str, what: str) -> str:
    """hk_slip_* / hk_bounds_* (scalar or lane) for one disc."""
    sfx = "u" if disc == "upper" else "l"
    mech = "k, t, thu, thl, wu, wl, x, yy, vx, vy, Y, nm, PT, brake" if lane else "t, y, p, brake"
    body: list[str] = []
    levels: list[str] = []
    fixed_needed = False
    for i, eff in enumerate(comp.effects):
        if not (issubclass(eff, Friction) and eff.disc == disc):
            continue
        ctx = HookContext(lane, comp, i, disc)
        fns = eff.defined_functions()
        sw = switch_condition(comp, lane, i)
        chosen = []
        if what == "slip" and "slip" in fns:
            chosen.append(f"T = {call_effect(comp, ctx, 'slip')}")
        if what == "bounds" and "stick" in fns:
            chosen.append(f"lo, hi = {call_effect(comp, ctx, 'stick')}")
        body.extend(guarded(chosen, sw))
        if "level" in fns:
            levels.append((call_effect(comp, ctx, "level"), sw))
        fixed_needed |= ctx.needs_fixed
    if levels and not any(sw for _, sw in levels):
        body.append("_g = " + " * ".join(c for c, _ in levels))
    elif levels:  # a skipped level is a factor of 1
        body.append("_g = 1.0")
        for c, sw in levels:
            body.extend(guarded([f"_g = _g * {c}"], sw))
    pro = fixed_frame_prologue(lane) if fixed_needed else []
    if what == "slip":
        sig = f"hk_slip_{sfx}{'_lane' if lane else ''}(T, d, aw, {mech})"
        ret = "_g * T" if levels else "T"
    else:
        sig = f"hk_bounds_{sfx}{'_lane' if lane else ''}(lo, hi, {mech})"
        ret = "_g * lo, _g * hi" if levels else "lo, hi"
    lines = [f"@{JIT}", f"def {sig}:"] + ["    " + ln for ln in pro + body] + [f"    return {ret}"]
    return "\n".join(lines) + "\n"


def _delay(comp: Composition) -> str:
    terms = []
    for i, eff in enumerate(comp.effects):
        if issubclass(eff, Delay):
            terms.append(call_effect(comp, HookContext(False, comp, i), "delay"))
    return f"@{JIT}\ndef hk_delay(p):\n    return {' + '.join(terms) if terms else '0.0'}\n"


def _measure(comp: Composition) -> str:
    lines = [f"@{JIT}", "def hk_measure(theta_u, theta_l, X, Y, omega_u, omega_l, p):"]
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
                args.append(a)  # a channel or a disc's speed
        call = f"_e{i}_measure({', '.join(args)})"
        ch = ", ".join(eff.channels)
        lines.append(
            f"    {ch}{',' if len(eff.channels) == 1 else ''} = {call}"
            if len(eff.channels) > 1
            else f"    {ch} = {call}"
        )
    lines.append("    return theta_u, theta_l, X, Y")
    lines += [
        "",
        "",
        "@njit(cache=True)",
        "def measure_arrays(TU, TL, X, Y, WU, WL, p):",
        "    n = TU.shape[0]",
        "    out = np.empty((4, n))",
        "    for i in range(n):",
        "        a, b, c, d = hk_measure(TU[i], TL[i], X[i], Y[i], WU[i], WL[i], p)",
        "        out[0, i] = a",
        "        out[1, i] = b",
        "        out[2, i] = c",
        "        out[3, i] = d",
        "    return out",
    ]
    return "\n".join(lines) + "\n"


def effect_file_copy(index: int) -> str:
    """The name of the copy of the composition's effect number ``index`` (an effect file) in its generated
    package: the hooks load the file from there, so the package does not depend on where the user keeps it."""
    return f"effect_{index}.py"


def _effect_imports(comp: Composition) -> list[str]:
    lines = []
    for i, eff in enumerate(comp.effects):
        origin = getattr(eff, "__drillgym_file__", None)
        if origin:
            here = f"_os.path.join(_os.path.dirname(__file__), {effect_file_copy(i)!r})"
            lines.append(f"_E{i} = _load_class({here}, {eff.__qualname__!r})")
        else:
            lines.append(f"from {eff.__module__} import {eff.__qualname__} as _E{i}")
        for fn in eff.defined_functions():
            lines.append(f"_e{i}_{fn} = {JIT}(_function(_E{i}, {fn!r}))")
            lines.append(f"_e{i}_{fn}_v = {JIT}(_simd(_function(_E{i}, {fn!r})))  # lane variant")
    return lines


def hooks_source(comp: Composition) -> str:
    """The generated hooks module of a composition.

    Parameters
    ----------
    comp : Composition
        The composition of effects.

    Returns
    -------
    str
        Python source of the module: the effects' functions compiled inline, the hooks
        ``hk_*`` the kernel templates call, and the composition's constants (``N_STATE``, ...).
    """
    parts = [
        f'"""Generated by drillgym.effects.codegen for the composition {comp.label!r}.  Do not edit."""',
        "",
        "import math",
        "import os as _os",
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
        _lane_params(comp),
        "",
        _rhs(comp, False),
        "",
        _effects_lane(comp),
        "",
        _rhs(comp, True),
        "",
        _lag(comp, False),
        "",
        _lag(comp, True),
        "",
        _lag_start(comp),
        "",
    ]
    for disc in ("upper", "lower"):
        for what in ("slip", "bounds"):
            parts += [_friction(comp, False, disc, what), ""]
        parts += [_friction(comp, True, disc, "bounds"), ""]
    parts += [_delay(comp), "", _measure(comp)]
    return "\n".join(parts)
