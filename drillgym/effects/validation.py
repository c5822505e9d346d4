"""Checks an effect class before it is compiled: every problem is one line naming the file,
the effect and what is wrong (an unknown argument or coordinate, a parameter without bounds,
a function that fails or returns NaN at a typical state of the rig, declared neutral values at
which the effect does not vanish)."""

from __future__ import annotations

import inspect
import math
from typing import Any

from ..params import PARAM_NAMES, RigParams
from .base import (
    CONFIGURATIONS,
    FRICTION_VOCABULARY,
    MEASUREMENT_CHANNELS,
    VOCABULARY,
    Delay,
    Effect,
    EffectError,
    Force,
    Friction,
    Input,
    Measurement,
    Parameter,
    State,
    is_identifier,
)
from .quantities import QUANTITY_UNITS, allowed_arguments, describe_allowed

__all__ = ["validate_effect", "check_neutral"]

_FORCE_TARGETS = ("upper", "lower", "string", "lateral")
_DISCS = ("upper", "lower")

# typical states of the rig at which every function is probed (finite results required)
_PROBES = (
    dict(t=0.0, u=0.0, theta_u=0.0, theta_l=0.0, omega_u=0.0, omega_l=0.0, x=0.0, y=0.0, vx=0.0, vy=0.0),
    dict(t=12.5, u=2.5, theta_u=31.0, theta_l=31.7, omega_u=5.0, omega_l=7.5, x=1e-3, y=-5e-4, vx=2e-3, vy=1e-3),
    dict(t=3.0, u=-1.0, theta_u=-4.0, theta_l=-4.9, omega_u=-2.0, omega_l=-0.5, x=-2e-3, y=1e-3, vx=-1e-3, vy=0.0),
)


def _where(cls: type[Effect]) -> str:
    return f"{cls.source_file()}: effect {getattr(cls, 'name', '') or cls.__name__!r}"


def _check_parameter(cls: type[Effect], prm: Any) -> None:
    w = _where(cls)
    if not isinstance(prm, Parameter):
        raise EffectError(
            f"{w}: parameters must be drillgym.effects.Parameter(name, unit, lo, hi, guess, scale, doc), got {prm!r}"
        )
    if not is_identifier(prm.name):
        raise EffectError(f"{w}: parameter name {prm.name!r} is not a Python identifier")
    if (
        prm.name in PARAM_NAMES
        or prm.name in VOCABULARY
        or prm.name in FRICTION_VOCABULARY
        or prm.name in MEASUREMENT_CHANNELS
    ):
        raise EffectError(f"{w}: parameter name {prm.name!r} is already taken (a base parameter or an argument name)")
    if prm.neutral is not None and not (isinstance(prm.neutral, (int, float)) and prm.lo <= prm.neutral <= prm.hi):
        raise EffectError(
            f"{w}: parameter {prm.name!r}: neutral = {prm.neutral!r} is not a number within its bounds "
            f"[{prm.lo}, {prm.hi}]"
        )
    for attr in ("lo", "hi", "guess", "scale"):
        v = getattr(prm, attr)
        if v is None or isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise EffectError(
                f"{w}: parameter {prm.name!r} needs a finite {attr} (bounds, guess and scale are "
                f"required for fitting), got {v!r}"
            )
    if not prm.lo < prm.hi:
        raise EffectError(f"{w}: parameter {prm.name!r} has bounds lo = {prm.lo} >= hi = {prm.hi}")
    if not prm.lo <= prm.guess <= prm.hi or not prm.lo <= prm.value <= prm.hi:
        raise EffectError(f"{w}: parameter {prm.name!r}: guess/default outside its bounds [{prm.lo}, {prm.hi}]")
    if prm.scale <= 0:
        raise EffectError(f"{w}: parameter {prm.name!r} needs a positive scale, got {prm.scale}")


def _probe_values(cls: type[Effect], probe: dict[str, float], fn: str, disc: str | None) -> dict[str, float]:
    base = RigParams().to_dict()
    vals: dict[str, float] = dict(base)
    vals.update({p.name: p.value for p in cls.parameters})
    vals.update({s.name: 0.1 for s in cls.states})
    vals.update(probe)
    vals["alpha"] = probe["theta_l"] - probe["theta_u"]
    vals["alpha_dot"] = probe["omega_l"] - probe["omega_u"]
    c, s = math.cos(probe["theta_u"]), math.sin(probe["theta_u"])
    vals["X"] = probe["x"] * c - probe["y"] * s
    vals["Y"] = probe["x"] * s + probe["y"] * c
    vals["VX"] = c * probe["vx"] - s * probe["vy"] - vals["Y"] * probe["omega_u"]
    vals["VY"] = s * probe["vx"] + c * probe["vy"] + vals["X"] * probe["omega_u"]
    vals["brake"] = 1.0
    if disc is not None:
        w = probe["omega_u"] if disc == "upper" else probe["omega_l"]
        vals.update(
            omega=w,
            speed=abs(w),
            direction=1.0 if w >= 0 else -1.0,
            theta=probe["theta_u"] if disc == "upper" else probe["theta_l"],
            T=0.3 if w >= 0 else -0.3,
            lo=-0.3,
            hi=0.3,
        )
    vals["theta_u"], vals["theta_l"] = probe["theta_u"], probe["theta_l"]
    return vals


def _expected_outputs(cls: type[Effect], fn: str) -> int:
    if fn == "derivative":
        return len(cls.states)
    if fn == "force" or fn == "stick":
        return 2
    if fn == "measure":
        return len(cls.channels)
    return 1


def validate_effect(cls: Any) -> None:
    """Raise EffectError (file, effect, problem) when ``cls`` cannot be compiled into the kernels."""
    if not (inspect.isclass(cls) and issubclass(cls, Effect)) or not cls.kind:
        raise EffectError(
            f"{cls!r} is not an effect: subclass drillgym.effects.Force, Friction, Input, Delay or Measurement"
        )
    w = _where(cls)
    if "<locals>" in cls.__qualname__:  # the compiled kernels import it by module and name
        raise EffectError(f"{w}: the effect class is defined inside a function; define it at a module's top level")
    if not is_identifier(cls.name):
        raise EffectError(f"{w}: the effect needs a name that is a Python identifier (class attribute name = ...)")
    bad_cfg = [c for c in cls.configurations if c not in CONFIGURATIONS]
    if bad_cfg:
        raise EffectError(
            f"{w}: unknown configuration(s) {', '.join(map(repr, bad_cfg))}; "
            f"expected some of {', '.join(CONFIGURATIONS)}"
        )
    for prm in cls.parameters:
        _check_parameter(cls, prm)
    names = [p.name for p in cls.parameters]
    if len(set(names)) != len(names):
        raise EffectError(f"{w}: two parameters share a name")
    for st in cls.states:
        if not isinstance(st, State) or not is_identifier(st.name):
            raise EffectError(f"{w}: states must be drillgym.effects.State(name, unit, doc) with identifier names")
        if st.name in PARAM_NAMES or st.name in VOCABULARY or st.name in names:
            raise EffectError(f"{w}: state name {st.name!r} is already taken")
    fns = cls.defined_functions()
    disc = None
    if issubclass(cls, Force):
        if cls.acts_on not in _FORCE_TARGETS:
            raise EffectError(
                f"{w}: acts_on = {cls.acts_on!r} is not a coordinate; expected one of {', '.join(_FORCE_TARGETS)}"
            )
        need = "force" if cls.acts_on == "lateral" else "torque"
        if need not in fns:
            raise EffectError(f"{w}: a Force acting on {cls.acts_on!r} defines {need}(...)")
        fns = {k: v for k, v in fns.items() if k in (need, "derivative")}
    elif issubclass(cls, Friction):
        if cls.disc not in _DISCS:
            raise EffectError(f"{w}: disc = {cls.disc!r} is not a disc; expected 'upper' or 'lower'")
        if not {"slip", "stick", "level"} & set(fns):
            raise EffectError(f"{w}: a Friction effect defines slip(T, ...), stick(lo, hi, ...) or level(...)")
        disc = cls.disc
    elif issubclass(cls, (Input, Delay)):
        need = cls.functions[0]
        if need not in fns:
            raise EffectError(f"{w}: an {cls.kind.capitalize()} effect defines {need}(...)")
        lag = getattr(cls, "lag", None) or {}
        if not isinstance(lag, dict):
            raise EffectError(f"{w}: lag must be a dict state name -> time-constant parameter name")
        states = {s.name for s in cls.states if isinstance(s, State)}
        params = {p.name: p for p in cls.parameters if isinstance(p, Parameter)}
        for st, tau in lag.items():
            if st not in states or tau not in params:
                raise EffectError(f"{w}: lag {{{st!r}: {tau!r}}}: expected one of its states -> one of its parameters")
            if not params[tau].lo > 0.0:
                raise EffectError(f"{w}: lag time constant {tau!r} needs a lower bound > 0, got {params[tau].lo}")
    elif issubclass(cls, Measurement):
        bad = [c for c in cls.channels if c not in MEASUREMENT_CHANNELS]
        if bad or not cls.channels:
            raise EffectError(f"{w}: channels {cls.channels!r}: expected some of {', '.join(MEASUREMENT_CHANNELS)}")
        if "measure" not in fns:
            raise EffectError(f"{w}: a Measurement effect defines measure(...)")
        if cls.states:
            raise EffectError(f"{w}: a Measurement effect cannot have states")
    if cls.states and "derivative" not in fns:
        raise EffectError(f"{w}: it has states, so it defines derivative(...) returning their time derivatives")
    for fn, f in fns.items():
        params = inspect.signature(f).parameters
        if params and next(iter(params)) == "self":
            raise EffectError(
                f"{w}: {fn}(self, ...): write effect functions without self (they are compiled "
                f"as plain functions of the quantities they name)"
            )
        if any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params.values()):
            raise EffectError(f"{w}: {fn}(...) must name its arguments (no *args/**kwargs)")
        allowed = allowed_arguments(cls, fn)
        unknown = [a for a in params if a not in allowed]
        if unknown:
            raise EffectError(
                f"{w}: {fn}() asks for unknown quantity/coordinate {unknown[0]!r}; {describe_allowed(cls, fn)}"
            )
        _probe(cls, fn, f, list(params), disc)
    check_neutral(cls)


def _probe(cls: type[Effect], fn: str, f: Any, args: list[str], disc: str | None) -> None:
    w = _where(cls)
    n_out = _expected_outputs(cls, fn)
    for probe in _PROBES:
        vals = _probe_values(cls, probe, fn, disc)
        try:
            out = f(*[vals[a] for a in args])
        except Exception as exc:  # noqa: BLE001
            raise EffectError(f"{w}: {fn}() fails at a typical state ({type(exc).__name__}: {exc})") from None
        outs = out if isinstance(out, tuple) else (out,)
        if len(outs) != n_out:
            raise EffectError(f"{w}: {fn}() returns {len(outs)} value(s), expected {n_out}")
        for v in outs:
            try:
                fv = float(v)
            except (TypeError, ValueError):
                shown = str(v) if len(str(v)) <= 60 else str(v)[:57] + "..."
                raise EffectError(f"{w}: {fn}() returns {type(v).__name__} {shown}, not a number") from None
            if not math.isfinite(fv):
                shown = ", ".join(f"{a} = {_num(vals[a])}" for a in args)
                raise EffectError(f"{w}: {fn}() returns {fv} (not finite) at {shown}")


def _unchanged(cls: type[Effect], fn: str, vals: dict[str, float]) -> tuple[float, ...]:
    """What ``fn`` returns when the effect adds nothing."""
    if fn == "torque" or fn == "delay":
        return (0.0,)
    if fn == "force":
        return (0.0, 0.0)
    if fn == "slip":
        return (vals["T"],)
    if fn == "stick":
        return (vals["lo"], vals["hi"])
    if fn == "level":
        return (1.0,)
    if fn == "voltage":
        return (vals["u"],)
    return tuple(vals[c] for c in cls.channels)  # measure


def _num(v: float, unit: str = "") -> str:
    """A number as a message shows it: plain float, 4 significant digits, with its unit."""
    return f"{float(v):.4g}" + (f" {unit}" if unit and unit != "-" else "")


def _at_state(args: list[str], vals: dict[str, float], skip: set[str]) -> str:
    """`` at omega_l = 7.5 rad/s, t = 12.5 s`` for the state quantities a function asks for (not its parameters)."""
    shown = [f"{a} = {_num(vals[a], QUANTITY_UNITS.get(a, ''))}" for a in args if a not in skip and a in QUANTITY_UNITS]
    return f" at {', '.join(shown)}" if shown else ""


#: quantities a function's neutral-value message already names as what it should have returned
_SHOWN_AS_INPUT = {
    "voltage": {"u"},
    "slip": {"T"},
    "stick": {"lo", "hi"},
    "torque": set(),
    "force": set(),
    "level": set(),
    "delay": set(),
}


def _neutral_meaning(cls: type[Effect], fn: str, outs: tuple[float, ...], want: tuple[float, ...], at: str) -> str:
    """What the function should do at its neutral values, and what it did, in the words of its kind."""
    if fn == "voltage":
        return (
            f"an Input effect at its neutral values must pass the voltage through unchanged: voltage() gives "
            f"{_num(outs[0], 'V')} for {_num(want[0], 'V')}{at}"
        )
    if fn == "torque":
        where = "in the string" if getattr(cls, "acts_on", "") == "string" else f"on the {cls.acts_on} disc"
        return f"a Force at its neutral values must add no torque: torque() gives {_num(outs[0], 'N m')} {where}{at}"
    if fn == "force":
        return (
            f"a Force at its neutral values must add no force: force() gives (FX, FY) = "
            f"({_num(outs[0])}, {_num(outs[1])}) N{at}"
        )
    if fn == "slip":
        return (
            f"a Friction effect at its neutral values must leave the slip torque unchanged: slip() gives "
            f"{_num(outs[0], 'N m')} for T = {_num(want[0], 'N m')}{at}"
        )
    if fn == "stick":
        return (
            f"a Friction effect at its neutral values must leave the stick set unchanged: stick() gives "
            f"({_num(outs[0])}, {_num(outs[1])}) N m for (lo, hi) = ({_num(want[0])}, {_num(want[1])}) N m{at}"
        )
    if fn == "level":
        return (
            f"a Friction effect at its neutral values must leave the friction level unchanged: level() gives "
            f"{_num(outs[0])} instead of 1{at}"
        )
    if fn == "delay":
        return f"a Delay effect at its neutral values must delay by nothing: delay() gives {_num(outs[0], 's')}"
    units = {"theta_u": "rad", "theta_l": "rad", "X": "m", "Y": "m"}
    got = ", ".join(f"{c} = {_num(o, units[c])}" for c, o in zip(cls.channels, outs))
    read = ", ".join(_num(v, units[c]) for c, v in zip(cls.channels, want))
    return (
        f"a Measurement effect at its neutral values must leave the reading unchanged: measure() gives {got} for {read}"
    )


def check_neutral(cls: type[Effect]) -> None:
    """An effect whose parameters all declare ``neutral`` must add nothing there (the kernels skip it):
    at the typical states, a torque or force of 0, a slip torque T, a stick set (lo, hi), a level of
    1, the voltage u, a delay of 0, the channels unchanged (to 1e-12).

    Raises
    ------
    EffectError
        One line: the file, the effect, the neutral values, what the kind must do there and what the
        function gives instead, at which state (plain numbers with units).
    """
    neutral = cls.neutral_values()
    if neutral is None:
        return
    w = _where(cls)
    disc = getattr(cls, "disc", None) if issubclass(cls, Friction) else None
    declared = ", ".join(f"{k} = {_num(v)}" for k, v in neutral.items())
    for fn, f in cls.defined_functions().items():
        args = list(inspect.signature(f).parameters)
        for probe in _PROBES:
            vals = {**_probe_values(cls, probe, fn, disc), **neutral}
            at = _at_state(args, vals, set(neutral) | _SHOWN_AS_INPUT.get(fn, set(MEASUREMENT_CHANNELS)))
            try:
                out = f(*[vals[a] for a in args])
                outs = tuple(float(o) for o in (out if isinstance(out, tuple) else (out,)))
            except Exception as exc:  # noqa: BLE001 - any failure of the user's function, in one line
                raise EffectError(
                    f"{w}: {fn}() fails at its declared neutral values ({declared}){at}: {type(exc).__name__}: {exc}"
                ) from None
            want = _unchanged(cls, fn, vals)
            if len(outs) != len(want):
                raise EffectError(f"{w}: {fn}() returns {len(outs)} value(s), expected {len(want)}")
            if any(not abs(a - b) <= 1e-12 * max(1.0, abs(b)) for a, b in zip(outs, want)):
                raise EffectError(
                    f"{w}: {_neutral_meaning(cls, fn, outs, want, at)} (declared neutral: {declared}); "
                    f"drop neutral= or fix the function"
                )
