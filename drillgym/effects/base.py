"""What an effect is: a small piece of physics added to the rig's base model.

An effect is a class.  Its docstring-like attributes say what it is (``explanation``,
``signature``: the residual it leaves when missing), ``parameters`` and ``states``
say what it owns, and one or more plain functions give its physics.  The functions
name their arguments after the quantities they need, so an effect reads like the
paragraph it implements::

    class StringCubic(Force):
        name = "string_cubic"
        acts_on = "string"
        parameters = (Parameter("c3", "1/rad^2", lo=-50, hi=50, guess=0.0, scale=0.5,
                                doc="relative cubic stiffness of the string"),)

        def torque(alpha, ktheta, c3):          # N m, in the sense of ktheta * alpha
            return ktheta * c3 * alpha ** 3

The functions are compiled (numba, nopython) into the exact stick/slip kernels for the
composition of effects a run uses (:mod:`drillgym.effects.codegen`); they take and return
floats.  Argument names come from the vocabulary below, the base parameters
(:data:`drillgym.params.PARAM_INFO`: ``Ju, km, ..., Ts, Tc, ws, delta, ...``), the effect's own
parameters and its own states.

Kinds (one base class each):

==============  ============================================================================
``Force``       an extra generalised force: ``torque(...)`` (N m) on the ``"upper"`` or
                ``"lower"`` disc or in the ``"string"`` (added to ktheta*alpha: pulls the upper
                disc forward, the lower back), or ``force(...) -> (FX, FY)`` (N, fixed frame)
                on the lower disc's centre (``"lateral"``).
``Friction``    a change of a disc's friction law (``disc = "upper" | "lower"``): ``slip(T, ...)``
                the new slip torque from the law's ``T``; ``stick(lo, hi, ...)`` the new stick
                set; ``level(...)`` a factor on both.  Stick stays exact and set-valued: the
                kernels keep the disc at zero speed while its holding torque is in [lo, hi].
``Input``       a transformation of the voltage on its way to the motor: ``voltage(u, ...)``
                (dead zone, saturation, a lag with a state ...).  A first-order lag state
                (tau ds/dt = u - s, u the voltage entering the effect) is declared in ``lag``
                (state name -> time-constant parameter name): the kernels then integrate it
                exactly over each step, stable for any tau > 0 however small against the step.
``Delay``       a transport delay of the command: ``delay(...)`` in s (at most the bound of
                the parameter it uses).
``Measurement`` a transformation of measured channels (``channels`` among theta_u, theta_l,
                X, Y): ``measure(...)`` returns their new values in that order.
==============  ============================================================================

Any kind may own continuous ``states`` with ``derivative(...)`` returning their time
derivatives (a tuple when there are several); they are integrated with the rig's state.
"""

from __future__ import annotations

import inspect
import keyword
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

from ..errors import EffectError

__all__ = [
    "EffectError",
    "Parameter",
    "State",
    "Effect",
    "Force",
    "Friction",
    "Input",
    "Delay",
    "Measurement",
    "KINDS",
    "VOCABULARY",
    "CONFIGURATIONS",
]

CONFIGURATIONS = ("upper", "torsional", "lateral", "coupled", "free_vibration")

#: argument names every effect function may use (besides parameters and its own states)
VOCABULARY: dict[str, str] = {
    "t": "time since the start of the run (s)",
    "u": "voltage (V): for Input effects the voltage entering the effect, else the voltage at the motor",
    "theta_u": "upper disc angle (rad)",
    "theta_l": "lower disc angle (rad)",
    "omega_u": "upper disc speed (rad/s)",
    "omega_l": "lower disc speed (rad/s)",
    "alpha": "twist of the string theta_l - theta_u (rad)",
    "alpha_dot": "twist rate omega_l - omega_u (rad/s)",
    "x": "lower disc centre x, frame rotating with the upper disc (m)",
    "y": "lower disc centre y, frame rotating with the upper disc (m)",
    "vx": "dx/dt in the rotating frame (m/s)",
    "vy": "dy/dt in the rotating frame (m/s)",
    "X": "lower disc centre X, fixed (LVDT) frame (m)",
    "Y": "lower disc centre Y, fixed (LVDT) frame (m)",
    "VX": "velocity X of the lower disc centre, fixed frame (m/s)",
    "VY": "velocity Y of the lower disc centre, fixed frame (m/s)",
    "brake": "1.0 when the brake is on (torsional, coupled), else 0.0",
}
#: extra names of Friction functions
FRICTION_VOCABULARY: dict[str, str] = {
    "T": "slip torque of the law so far (N m, signed like the speed)",
    "direction": "slip direction of the disc (+1.0 / -1.0)",
    "speed": "speed magnitude of the disc (rad/s)",
    "omega": "signed speed of the disc (rad/s)",
    "theta": "angle of the disc (rad)",
    "lo": "lower end of the stick set so far (N m)",
    "hi": "upper end of the stick set so far (N m)",
}
MEASUREMENT_CHANNELS = ("theta_u", "theta_l", "X", "Y")


@dataclass(frozen=True)
class Parameter:
    """A parameter of an effect, with what fitting needs.

    Parameters
    ----------
    name : str
        Identifier used in the effect's functions and everywhere parameters are named.
    unit : str
        SI unit (text).
    lo, hi : float
        Physical bounds (finite; the effect is refused outside them).
    guess : float
        Initial guess for fitting (inside the bounds).
    scale : float
        Typical magnitude (> 0): scales the fit and its finite-difference step.
    doc : str, optional
        One line of meaning.
    default : float, optional
        Value when the effect is added without one (default: ``guess``).
    neutral : float, optional
        Value at which this parameter switches the effect off (optional).  When every parameter of an effect
        declares one and all sit there, the effect must add nothing (a torque of 0, a friction factor of 1,
        ...): the batch kernels then skip its functions, and the diagnosis starts a candidate there (checked by
        :func:`drillgym.effects.validation.check_neutral`).
    """

    name: str
    unit: str
    lo: float
    hi: float
    guess: float
    scale: float
    doc: str = ""
    default: float | None = None
    neutral: float | None = None

    @property
    def value(self) -> float:
        """The value used when none is given."""
        return float(self.guess if self.default is None else self.default)


@dataclass(frozen=True)
class State:
    """A continuous state an effect owns (integrated with the rig's state).

    Parameters
    ----------
    name : str
        Identifier, the argument name under which the effect's functions receive the state.
    unit : str
        SI unit (text).
    doc : str, optional
        One line of meaning.
    """

    name: str
    unit: str
    doc: str = ""


class Effect:
    """Base class of all effects (subclass one of the kinds: Force, Friction, Input, Delay, Measurement).

    A subclass declares what the effect is in class attributes and gives its physics in plain
    functions (see the module docstring and the kinds).  An instance carries parameter values:
    ``MotorLag(tau_m=0.02)``.

    Parameters
    ----------
    **values : float
        Parameter values by name, in each parameter's unit; names not given take their
        :attr:`Parameter.value`.

    Attributes
    ----------
    name : str
        Identifier of the effect (``effects=["name", ...]``, the command line, reports).
    kind : str
        ``"force"``, ``"friction"``, ``"input"``, ``"delay"`` or ``"measurement"`` (set by the kind).
    parameters : tuple of Parameter
        The parameters the effect owns.
    states : tuple of State
        Continuous states it owns; then ``derivative(...)`` returns their time derivatives.
    explanation : str
        The physics in words.
    signature : str
        The residual the effect leaves in a fit when it is missing (diagnosis hint).
    configurations : tuple of str
        Rig configurations the effect applies to.
    needs : tuple of str
        What a recording must contain for the effect to be identifiable (diagnosis hints).
    values : dict of str to float
        This instance's parameter values by name.

    Raises
    ------
    EffectError
        An unknown parameter name, a value that is not a number or lies outside its bounds.
    """

    kind: ClassVar[str] = ""
    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    states: ClassVar[tuple[State, ...]] = ()
    explanation: ClassVar[str] = ""
    signature: ClassVar[str] = ""
    configurations: ClassVar[tuple[str, ...]] = CONFIGURATIONS
    #: what a recording must contain for the effect to be identifiable (diagnosis hints)
    needs: ClassVar[tuple[str, ...]] = ()
    #: the functions a kind provides (validated and compiled)
    functions: ClassVar[tuple[str, ...]] = ()
    #: what the order of the effects means for this kind (``describe`` prints it)
    order_note: ClassVar[str] = ""

    def __init__(self, **values: float) -> None:
        known = {p.name: p for p in self.parameters}
        unknown = set(values) - set(known)
        if unknown:
            raise EffectError(
                f"effect {self.name!r}: unknown parameter(s) {', '.join(sorted(unknown))}; "
                f"it has {', '.join(known) or 'none'}"
            )
        self.values: dict[str, float] = {}
        for n, prm in known.items():
            v = values.get(n, prm.value)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise EffectError(f"effect {self.name!r}: parameter {n!r} must be a number, got {v!r}") from None
            if not (math.isfinite(v) and prm.lo <= v <= prm.hi):
                raise EffectError(
                    f"effect {self.name!r}: parameter {n!r} = {v} {prm.unit} is outside [{prm.lo}, {prm.hi}]"
                )
            self.values[n] = v

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v:g}" for k, v in self.values.items())
        return f"{type(self).__name__}({vals})"

    # ------------------------------------------------------------------ class-level helpers
    @classmethod
    def defined_functions(cls) -> dict[str, Callable[..., Any]]:
        """The physics functions this effect defines (name -> plain function)."""
        out = {}
        for fn in cls.functions + (("derivative",) if cls.states else ()):
            f = inspect.getattr_static(cls, fn, None)
            if f is None:
                continue
            if isinstance(f, (staticmethod, classmethod)):
                f = f.__func__
            if callable(f):
                out[fn] = f
        return out

    @classmethod
    def neutral_values(cls) -> dict[str, float] | None:
        """The parameter values at which the effect vanishes, or None when a parameter (or a
        state) leaves that undeclared: such an effect is never skipped."""
        if cls.states or not cls.parameters or any(p.neutral is None for p in cls.parameters):
            return None
        return {p.name: float(p.neutral) for p in cls.parameters}

    @classmethod
    def argument_names(cls, function: str) -> tuple[str, ...]:
        """The argument names of one of the effect's physics functions (e.g. ``"torque"``)."""
        return tuple(inspect.signature(cls.defined_functions()[function]).parameters)

    @classmethod
    def source_file(cls) -> str:
        """The file that defines the effect (``"<unknown file>"`` when there is none)."""
        try:
            return inspect.getsourcefile(cls) or "<unknown file>"
        except TypeError:
            return "<unknown file>"

    @classmethod
    def describe(cls) -> str:
        """Several lines: name, kind, parameters with units and bounds, explanation, signature."""
        lines = [f"{cls.name} ({cls.kind}; {', '.join(cls.configurations)})"]
        for p in cls.parameters:
            lines.append(f"  {p.name:<10} {p.unit:<10} [{p.lo:g}, {p.hi:g}] guess {p.guess:g}  {p.doc}")
        for s in cls.states:
            lines.append(f"  state {s.name} ({s.unit})  {s.doc}")
        if cls.explanation:
            lines.append("  physics: " + " ".join(cls.explanation.split()))
        if cls.signature:
            lines.append("  residual when missing: " + " ".join(cls.signature.split()))
        if cls.order_note:
            lines.append("  order: " + cls.order_note)
        return "\n".join(lines)


class Force(Effect):
    """An extra generalised force on a disc, in the string or on the lower disc's centre.

    Define ``torque(...)`` (N m) for ``acts_on`` ``"upper"``, ``"lower"`` or ``"string"``, or
    ``force(...) -> (FX, FY)`` (N, fixed frame) for ``"lateral"``.

    Parameters
    ----------
    **values : float
        Parameter values by name, as :class:`Effect`.

    Attributes
    ----------
    acts_on : str
        ``"upper"`` or ``"lower"``: a torque on that disc, positive in the positive sense of rotation;
        ``"string"``: a torque added to ``ktheta * alpha`` (+torque on the upper disc, -torque on the
        lower); ``"lateral"``: a force on the lower disc's centre.
    """

    kind = "force"
    acts_on: ClassVar[str] = ""
    functions = ("torque", "force")


class Friction(Effect):
    """A change of a disc's friction law.

    Define any of ``slip(T, ...)`` (the new slip torque, N m, signed like the speed, from the law's
    ``T``), ``stick(lo, hi, ...)`` (the new stick set (lo, hi), N m) and ``level(...)`` (a factor on
    both).  Slip and stick changes apply in the order the effects are given, level factors last.
    Stick stays exact and set-valued: the kernels keep the disc at zero speed while its holding
    torque is in [lo, hi].

    Parameters
    ----------
    **values : float
        Parameter values by name, as :class:`Effect`.

    Attributes
    ----------
    disc : str
        ``"upper"`` or ``"lower"`` (default).
    """

    kind = "friction"
    disc: ClassVar[str] = "lower"
    functions = ("slip", "stick", "level")


class Input(Effect):
    """A transformation of the voltage on its way to the motor: define ``voltage(u, ...)`` (V).

    The kernels integrate a declared lag exactly over each step (the entering voltage held at its
    value at the step start, exact for a command held over the step), so a time constant far below
    the step stays stable; an undeclared stiff state would make the explicit Runge-Kutta step
    diverge when its time constant is below about 0.36 dt.

    Parameters
    ----------
    **values : float
        Parameter values by name, as :class:`Effect`.

    Attributes
    ----------
    lag : dict of str to str
        First-order lag states, state name -> time-constant parameter name, e.g. ``{"u_m": "tau_m"}``
        for tau_m du_m/dt = u - u_m with u the voltage entering the effect (``derivative`` must say the
        same; the equilibria and the validation use it).
    """

    kind = "input"
    functions = ("voltage",)
    order_note = (
        "Input effects act in the order they are added (--add-effect, effects=[...]): the first added is nearest "
        "the command, the last nearest the motor; effects read from --params come before those added"
    )
    lag: ClassVar[dict[str, str]] = {}


class Delay(Effect):
    """A transport delay of the commanded voltage: define ``delay(...)`` (s).

    The delay depends on parameters only and is at most the upper bound of the parameters it uses,
    which sizes the delay line.

    Parameters
    ----------
    **values : float
        Parameter values by name, as :class:`Effect`.
    """

    kind = "delay"
    functions = ("delay",)
    order_note = "delays act on the command before any Input effect, wherever they are added; several delays add up"


class Measurement(Effect):
    """A transformation of measured channels: define ``measure(...)``.

    ``measure`` returns the new values of ``channels`` in that order (a tuple when several; rad for
    the angles, m for X and Y).

    Parameters
    ----------
    **values : float
        Parameter values by name, as :class:`Effect`.

    Attributes
    ----------
    channels : tuple of str
        The channels it changes, among ``"theta_u"``, ``"theta_l"``, ``"X"``, ``"Y"``.
    """

    kind = "measurement"
    channels: ClassVar[tuple[str, ...]] = ()
    functions = ("measure",)


KINDS: dict[str, type[Effect]] = {c.kind: c for c in (Force, Friction, Input, Delay, Measurement)}


def is_identifier(name: str) -> bool:
    """True when ``name`` is a Python identifier and not a keyword."""
    return isinstance(name, str) and name.isidentifier() and not keyword.iskeyword(name)
