"""A composition: the base model plus an ordered set of effects, with its parameter and state layout.

>>> from drillgym.effects import compose
>>> comp, values = compose(["motor_lag", "examples/effects/string_cubic.py:string_cubic"])
>>> comp.param_names[-2:], comp.state_names          # ('tau_m', 'c3'), ('u_m',)
>>> p = comp.vector(RigParams(), {"tau_m": 0.02, "c3": 1.5})   # the kernels' parameter vector
>>> comp.kernels.stepping.run_batch_serial                      # compiled for this composition

The kernels' parameter vector is the base parameters (``RigParams.to_vector`` layout) followed
by the effects' parameters in order; the state vector is the 8 mechanical states followed by
the effects' states; recorded outputs are the base columns followed by the effects' states.
"""

from __future__ import annotations

import inspect
import math
import threading
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..configurations import STATE_NAMES
from ..errors import InputTypeError
from ..integrators import OUTPUT_NAMES
from ..params import N_PARAMS, PARAM_INFO, PARAM_NAMES, ParameterError, RigParams
from .base import Delay, Effect, EffectError, Input, Measurement, Parameter
from .registry import resolve_effect
from .validation import validate_effect

__all__ = ["Composition", "compose", "EffectsLike", "BASE"]

EffectsLike = "Sequence[str | type[Effect] | Effect] | Composition | None"

_LOCK = threading.RLock()
_CACHE: dict[tuple, Composition] = {}


class Composition:
    """The base model and an ordered tuple of effect classes (validated); one per distinct tuple.

    ``Composition(effects)`` takes the effect classes in the order their changes apply (default: none,
    the base model) and returns the cached instance of that tuple.

    Attributes
    ----------
    names : tuple of str
        The effects' names.
    param_names : tuple of str
        Base parameters, then the effects' parameters: the layout of a parameter vector.
    state_names : tuple of str
        The effects' states; ``full_state_names`` prefixes the 8 mechanical states.

    Raises
    ------
    EffectError
        An invalid effect, an effect given twice, or two effects sharing a parameter or state name.
    """

    def __new__(cls, effects: Sequence[type[Effect]] = ()) -> Composition:
        key = tuple(effects)
        with _LOCK:
            if key in _CACHE:
                return _CACHE[key]
            self = super().__new__(cls)
            self._init(key)
            _CACHE[key] = self
            return self

    def _init(self, effects: tuple[type[Effect], ...]) -> None:
        for e in effects:
            validate_effect(e)
        names = [e.name for e in effects]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise EffectError(f"effect {sorted(dup)[0]!r} is given twice")
        pnames = [p.name for e in effects for p in e.parameters]
        clash = {n for n in pnames if pnames.count(n) > 1}
        if clash:
            raise EffectError(f"two effects share the parameter name {sorted(clash)[0]!r}: rename one")
        snames = [s.name for e in effects for s in e.states]
        if len(set(snames)) != len(snames):
            raise EffectError("two effects share a state name: rename one")
        self.effects = effects
        self.names = tuple(names)
        self.effect_param_names = tuple(pnames)
        self.param_names = PARAM_NAMES + self.effect_param_names
        self.n_params = len(self.param_names)
        self._pindex = {n: i for i, n in enumerate(self.param_names)}
        self.state_names = tuple(snames)
        self.n_states = len(snames)
        self._sindex = {n: j for j, n in enumerate(snames)}
        self.full_state_names = STATE_NAMES + self.state_names
        self.n_state = len(self.full_state_names)
        self.output_names = OUTPUT_NAMES + self.state_names
        self._params: dict[str, Parameter] = {p.name: p for e in effects for p in e.parameters}
        self._owner = {p.name: e for e in effects for p in e.parameters}
        self._kernels = None

    # ------------------------------------------------------------------ description
    @property
    def label(self) -> str:
        return "+".join(self.names) if self.names else "base"

    def __repr__(self) -> str:
        return f"Composition({self.label})"

    def specs(self) -> list[str]:
        """The effects as specs ``compose`` accepts in any process: a library or entry-point name,
        ``path/to/file.py:Class`` for a user file, ``module:Class`` for an importable class."""
        out = []
        for e in self.effects:
            origin = getattr(e, "__drillgym_file__", None)
            if origin:
                out.append(f"{origin}:{e.__qualname__}")
            elif e.__module__ == "drillgym.effects.library":
                out.append(e.name)
            else:
                out.append(f"{e.__module__}:{e.__qualname__}")
        return out

    def __reduce__(self):  # pickles by specs, so a user file's effect reaches worker processes
        return (_composition_from_specs, (self.specs(),))

    def __len__(self) -> int:
        return len(self.effects)

    def has_kind(self, kind: type[Effect]) -> bool:
        """True when one of the effects is of ``kind`` (Force, Friction, Input, Delay, Measurement)."""
        return any(issubclass(e, kind) for e in self.effects)

    @property
    def has_delay(self) -> bool:
        return self.has_kind(Delay)

    @property
    def has_measurement(self) -> bool:
        return self.has_kind(Measurement)

    @property
    def measurement_reads_speeds(self) -> bool:
        """True when a Measurement effect's reading depends on a disc's speed (``omega_u`` / ``omega_l``): the
        reading's rate then holds the reading's own change where the speed changes sign."""
        return any(
            issubclass(e, Measurement) and {"omega_u", "omega_l"} & set(e.argument_names("measure"))
            for e in self.effects
        )

    @property
    def measurement_columns(self) -> tuple[int, ...]:
        """Indices of the parameters the Measurement effects read (their own and any base parameter
        their ``measure`` names): rows equal there are measured alike."""
        cols = set()
        for eff in self.effects:
            if issubclass(eff, Measurement):
                cols |= {self._pindex[a] for a in eff.argument_names("measure") if a in self._pindex}
        return tuple(sorted(cols))

    def param_index(self, name: str) -> int:
        """Index of parameter ``name`` (base or effect) in a parameter vector; ParameterError if unknown."""
        try:
            return self._pindex[name]
        except KeyError:
            raise ParameterError(
                f"unknown parameter {name!r} for the model {self.label!r}; it has: {', '.join(self.param_names)}"
            ) from None

    @property
    def lag_state_columns(self) -> tuple[int, ...]:
        """State-vector indices (8 + j) of the first-order lag states the Input effects declare
        (``Input.lag``): left NaN in an initial state, the kernels start them at the first command
        held before the start, the history the delay lines assume."""
        return tuple(8 + self._sindex[st] for e in self.effects for st in (getattr(e, "lag", None) or {}))

    def state_index(self, name: str) -> int:
        """Index of an effect state among the effects' states (its state-vector index is 8 + this)."""
        return self._sindex[name]

    def parameter(self, name: str) -> Parameter:
        """The Parameter (unit, bounds, guess, scale, doc) of an effect parameter."""
        if name in self._params:
            return self._params[name]
        if name in PARAM_INFO:
            i = PARAM_INFO[name]
            v = getattr(RigParams(), name)
            return Parameter(name, i["unit"], i["lo"], i["hi"], v, max(abs(v), 1e-9), i["doc"])
        raise ParameterError(f"unknown parameter {name!r} for the model {self.label!r}")

    def owner(self, name: str) -> type[Effect] | None:
        """The effect that owns parameter ``name`` (None for a base parameter)."""
        return self._owner.get(name)

    def default_values(self) -> dict[str, float]:
        """Every effect parameter's default value by name."""
        return {n: p.value for n, p in self._params.items()}

    # ------------------------------------------------------------------ parameter vectors
    def check_values(self, values: Mapping[str, float]) -> dict[str, float]:
        """Effect parameter values completed with defaults and checked against their bounds.

        Parameters
        ----------
        values : mapping of str to float
            Effect parameter values by name, in each parameter's unit.

        Returns
        -------
        dict of str to float
            Every effect parameter's value.

        Raises
        ------
        ParameterError
            An unknown name, or a value that is not a number or lies outside its bounds.
        """
        unknown = set(values) - set(self._params)
        if unknown:
            n = sorted(unknown)[0]
            hint = f"; the model {self.label!r} has {', '.join(self._params) or 'no effect parameters'}"
            raise ParameterError(f"unknown effect parameter {n!r}{hint}")
        out = self.default_values()
        for n, v in values.items():
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise ParameterError(f"effect parameter {n!r} must be a number, got {v!r}") from None
            prm = self._params[n]
            if not (math.isfinite(v) and prm.lo <= v <= prm.hi):
                raise ParameterError(
                    f"effect parameter {n!r} = {v} {prm.unit} is outside [{prm.lo}, {prm.hi}] "
                    f"(effect {self._owner[n].name})"
                )
            out[n] = v
        return out

    def vector(self, params: RigParams | None = None, values: Mapping[str, float] | None = None) -> np.ndarray:
        """The kernels' parameter vector: base parameters, then the effects' (defaults where not given).

        Parameters
        ----------
        params : RigParams, optional
            Base parameters; default the identified set.
        values : mapping of str to float, optional
            Effect parameter values by name.

        Returns
        -------
        ndarray
            (n_params,) float64 in the layout of :attr:`param_names`.
        """
        base = (params or RigParams()).to_vector()
        vals = self.check_values(values or {})
        return np.concatenate([base, np.array([vals[n] for n in self.effect_param_names], dtype=np.float64)])

    def split(self, vec: np.ndarray) -> tuple[RigParams, dict[str, float]]:
        """Split a parameter vector into base parameters and effect values.

        Parameters
        ----------
        vec : ndarray
            (n_params,) vector in the layout of :attr:`param_names`.

        Returns
        -------
        RigParams
            The base parameters.
        dict of str to float
            The effect parameters by name.
        """
        vec = np.asarray(vec, dtype=float)
        if vec.shape != (self.n_params,):
            raise ParameterError(f"parameter vector of {self.label!r} has {self.n_params} entries, got {vec.shape}")
        return (
            RigParams.from_vector(vec[:N_PARAMS]),
            {n: float(v) for n, v in zip(self.effect_param_names, vec[N_PARAMS:])},
        )

    def named(self, vec: np.ndarray) -> dict[str, float]:
        """All parameters of a vector by name."""
        return {n: float(v) for n, v in zip(self.param_names, np.asarray(vec, dtype=float))}

    def matrix(self, params: Any, n: int, values: Mapping[str, float] | None = None) -> np.ndarray:
        """The (n, n_params) parameter matrix of n runs.

        Parameters
        ----------
        params : RigParams, sequence of RigParams, ndarray or None
            One parameter set for all runs, one per run, or a matrix with n (or 1) rows of the base
            parameters (effect values appended from ``values``) or of all parameters.
        n : int
            Number of runs.
        values : mapping of str to float, optional
            Effect parameter values by name, for rows given without them.

        Returns
        -------
        ndarray
            (n, n_params) float64, C-contiguous.

        Raises
        ------
        ParameterError
            A matrix of the wrong width or with non-finite entries.
        InputTypeError
            ``params`` of another type.
        """
        if params is None or isinstance(params, RigParams):
            return np.tile(self.vector(params, values), (n, 1))
        if isinstance(params, np.ndarray) and params.dtype != object:
            P = np.atleast_2d(np.asarray(params, dtype=np.float64))
            if P.shape[1] == N_PARAMS and self.n_params > N_PARAMS:
                extra = self.vector(None, values)[N_PARAMS:]
                P = np.hstack([P, np.tile(extra, (P.shape[0], 1))])
            if P.shape[1] != self.n_params:
                raise ParameterError(
                    f"parameter matrix must have {self.n_params} columns ({self.label}), got {P.shape[1]}"
                )
            if P.shape[0] == 1:
                P = np.repeat(P, n, axis=0)
            if not np.all(np.isfinite(P)):
                raise ParameterError("parameter matrix contains NaN or inf")
            return np.ascontiguousarray(P)
        plist = list(params)
        if len(plist) == 1:
            plist = plist * n
        if not all(isinstance(q, RigParams) for q in plist):
            raise InputTypeError("params must be RigParams, a sequence of RigParams or a (B, n_params) array")
        return np.stack([self.vector(q, values) for q in plist])

    # ------------------------------------------------------------------ compiled model
    @property
    def kernels(self):
        """The compiled kernels of this composition (generated and cached on first use)."""
        if self._kernels is None:
            with _LOCK:
                if self._kernels is None:
                    from .codegen import build_kernels

                    self._kernels = build_kernels(self)
        return self._kernels

    def hook_calls(self):
        """The composition's hooks compiled for calls from Python (:mod:`.python_hooks`: ``delay_of``,
        ``longest_delay``, ``input_path``), loaded from numba's cache after the first process."""
        from .foreign_client import foreign_client

        return foreign_client(self.kernels, "drillgym.effects.python_hooks")

    def delay(self, vec: np.ndarray) -> float:
        """Transport delay of the command (s) at the parameter vector ``vec`` (``param_names`` order): the
        compiled ``hk_delay``; 0 without a Delay effect."""
        if not self.has_delay:
            return 0.0
        return float(self.hook_calls().delay_of(np.ascontiguousarray(vec, dtype=np.float64)))

    def delay_line_length(self, P: np.ndarray, dt: float) -> int:
        """Length of the per-trajectory delay line for parameter rows ``P`` and step ``dt`` (s).

        1 without a Delay effect; otherwise the longest delay of the rows in steps, plus 3.
        """
        if not self.has_delay:
            return 1
        d = self.hook_calls().longest_delay(np.ascontiguousarray(np.atleast_2d(P), dtype=np.float64))
        return int(math.ceil(max(d, 0.0) / dt)) + 3

    def measure(
        self,
        theta_u: np.ndarray,
        theta_l: np.ndarray,
        X: np.ndarray,
        Y: np.ndarray,
        vec: np.ndarray,
        omega_u: np.ndarray,
        omega_l: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The channels as the sensors read them (the Measurement effects applied).

        Parameters
        ----------
        theta_u, theta_l : ndarray
            Disc angles (rad).
        X, Y : ndarray
            Lateral position of the lower disc centre, fixed frame (m).
        vec : ndarray
            Parameter vector (:meth:`vector`).
        omega_u, omega_l : ndarray
            Disc speeds (rad/s), shaped as ``theta_u``: a reading may depend on the direction of motion.

        Returns
        -------
        tuple of ndarray
            ``(theta_u, theta_l, X, Y)`` as measured, shaped as ``theta_u``.
        """
        shape = np.shape(theta_u)
        if not self.has_measurement:
            return tuple(np.asarray(a, dtype=float).copy() for a in (theta_u, theta_l, X, Y))
        arrs = [  # writable copies: a read-only view would compile the kernel a second time
            np.require(np.broadcast_to(np.asarray(a, dtype=np.float64), shape).ravel(), np.float64, ("C", "W"))
            for a in (theta_u, theta_l, X, Y, omega_u, omega_l)
        ]
        out = self.kernels.hooks.measure_arrays(*arrs, np.asarray(vec, dtype=np.float64))
        return tuple(out[i].reshape(shape) for i in range(4))

    def not_acting_in(self, configuration: str) -> list[type[Effect]]:
        """The effects that do not act in ``configuration`` (a configuration label such as ``"torsional"``).

        Such an effect would change nothing in a run of that configuration, silently: the commands
        and :func:`drillgym.simulate` refuse it.
        """
        return [e for e in self.effects if e.configurations and configuration not in tuple(e.configurations)]

    def refuse_not_acting(self, configuration: str, option: str = "effects") -> None:
        """Refuse, in one line naming ``option``, an effect that does not act in ``configuration``.

        Parameters
        ----------
        configuration : str
            The configuration label of the run or the recording (``"torsional"``).
        option : str, optional
            The option or argument that named the effects, for the message.

        Raises
        ------
        EffectError
            The first effect of :meth:`not_acting_in`: it would change nothing, silently.
        """
        idle = self.not_acting_in(configuration)
        if idle:
            raise EffectError(
                f"{option} {idle[0].name}: the effect does not act in the {configuration} configuration (it acts "
                f"in {', '.join(idle[0].configurations)}); leave it out"
            )

    def signal_path(self, among: Iterable[str] | None = None) -> list[str]:
        """The path of the command to the motor: the Delay effects (their delays add up, so their order does not
        matter), then the Input effects in the composition's order, the first nearest the command.

        Parameters
        ----------
        among : iterable of str, optional
            Only these effects (e.g. those a diagnosis selected); default all.

        Returns
        -------
        list of str
            Effect names, command side first; empty when the composition has neither kind.

        Examples
        --------
        >>> comp, _ = compose(["input_delay", "examples/effects/motor_dead_zone.py:dead_zone", "motor_lag"])
        >>> comp.signal_path()        # the motor sees lag(dead_zone(u(t - delay)))
        ['input_delay', 'dead_zone', 'motor_lag']
        """
        keep = set(self.names if among is None else among)
        delays = [e.name for e in self.effects if issubclass(e, Delay) and e.name in keep]
        return delays + [e.name for e in self.effects if issubclass(e, Input) and e.name in keep]

    def order_fields(self, name: str) -> dict[str, Any]:
        """What a JSON record of effect ``name`` says about where it acts: ``{"kind": ...}`` and, for a
        Delay or Input effect, ``"signal_path_position"`` (1 = nearest the command, see :meth:`signal_path`).

        Parameters
        ----------
        name : str
            An effect of the composition.

        Returns
        -------
        dict
            ``{"kind": "input", "signal_path_position": 2}``, or ``{"kind": "force"}`` for an effect off the path.
        """
        eff = next((e for e in self.effects if e.name == name), None)
        if eff is None:
            raise EffectError(f"effect {name!r} is not in the model {self.label!r}; it has {', '.join(self.names)}")
        out: dict[str, Any] = {"kind": eff.kind}
        path = self.signal_path()
        if name in path:
            out["signal_path_position"] = path.index(name) + 1
        return out

    def describe(self) -> str:
        """Several lines: each effect's :meth:`Effect.describe`, or that it is the base model; with more than one
        effect on the command's path, that path (:meth:`signal_path`)."""
        if not self.effects:
            return "base model (no effects)"
        lines = [e.describe() for e in self.effects]
        path = self.signal_path()
        if len(path) > 1:
            lines.append("signal path from the command to the motor: command -> " + " -> ".join(path) + " -> motor")
        return "\n".join(lines)


BASE = None  # set below (the empty composition)


def _as_list(effects: Any) -> list:
    if effects is None:
        return []
    if isinstance(effects, (str, Effect)) or inspect.isclass(effects):
        return [effects]
    if isinstance(effects, Iterable):
        return list(effects)
    raise EffectError(
        f"effects must be an effect (a library name, 'path/to/file.py:NAME', an Effect class or instance) "
        f"or a sequence of them, got {effects!r}"
    )


def compose(effects: Any = None, values: Mapping[str, float] | None = None) -> tuple[Composition, dict[str, float]]:
    """(Composition, effect parameter values) from effects given by name, file spec, class or instance.

    Values come from instances (``MotorLag(tau_m=0.02)``), then ``values`` (by parameter name),
    then each parameter's default.

    Parameters
    ----------
    effects : str, Effect, Effect subclass, sequence of them, or Composition, optional
        Effects by library name (``"motor_lag"``), file spec (``"path/to/file.py:NAME"``), class or
        instance.  None: the base model.
    values : mapping of str to float, optional
        Effect parameter values by name, in each parameter's unit.

    Returns
    -------
    Composition
        The (cached) composition of the effects.
    dict of str to float
        Every effect parameter's value by name.

    Raises
    ------
    EffectError
        An unknown or invalid effect.
    ParameterError
        An unknown effect parameter, or a value that is not a number or lies outside its bounds.

    Examples
    --------
    >>> from drillgym.effects import compose
    >>> comp, values = compose(["motor_lag"], {"tau_m": 0.02})
    """
    if values is not None and not isinstance(values, Mapping):
        raise InputTypeError(
            f"effect_params must be a mapping of parameter names to values, got {type(values).__name__}"
        )
    if isinstance(effects, Composition):
        return effects, effects.check_values(values or {})
    classes: list[type[Effect]] = []
    vals: dict[str, float] = {}
    for spec in _as_list(effects):
        obj = resolve_effect(spec)
        if isinstance(obj, Effect):
            classes.append(type(obj))
            vals.update(obj.values)
        else:
            classes.append(obj)
    comp = Composition(tuple(classes))
    vals.update(values or {})
    return comp, comp.check_values(vals)


def _composition_from_specs(specs: list[str]) -> Composition:
    import importlib

    classes = []
    for s in specs:
        mod, sep, name = s.rpartition(":")
        if sep and not mod.endswith(".py"):
            obj = importlib.import_module(mod)
            for part in name.split("."):
                obj = getattr(obj, part)
            classes.append(obj)
        else:
            classes.append(resolve_effect(s))
    return Composition(tuple(classes))


def effect_names(effects: Iterable[type[Effect]]) -> list[str]:
    return [e.name for e in effects]


BASE = Composition(())
