"""The controller interface shared by the simulator harness, the Gymnasium envs and the rig.

A controller maps what the rig measures to a motor voltage, once per control
period (10 ms by default, the environments' period; a controller class may
declare another in :attr:`Controller.default_dt`).  Measurements are passed as a mapping ``name -> value``
(:data:`MEASUREMENTS`); every value is a scalar (one rig / one env) or an array
of shape (n,) (n trajectories stepped together by the evaluation harness).
A controller declares in :attr:`Controller.uses` which measurements it reads,
so a caller (env adapter, ``drillgym rig run``) knows what it must provide.

    >>> import controllers
    >>> c = controllers.make("observer", config="torsional", omega_ref=3.0)
    >>> c.reset({"t": 0.0, "theta_u": 0.0})
    >>> u = c({"t": 0.0, "theta_u": 0.0})        # volts, float for scalar input

Lifecycle: ``reset(measurement)`` at the start of an episode (it fixes the
batch size n and reads ``omega_ref`` from the measurement when present), then
``act(measurement)`` (or ``controller(measurement)``) every control period,
which returns the voltage to hold until the next call, clipped to
[-u_max, u_max].  The controller remembers the voltage it applied (``u_prev``),
which observers use as their known input.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from drillgym import Configuration, RigParams, parse_configuration
from drillgym.errors import InputError, InputTypeError
from drillgym.run_setup import real_number

__all__ = ["Controller", "MEASUREMENTS", "U_MAX", "DEFAULT_CONTROL_DT", "Measurement"]

U_MAX = 5.0  # V, the amplifier's range
DEFAULT_CONTROL_DT = 0.01  # s, control period

MEASUREMENTS = {
    "t": "time since reset (s)",
    "theta_u": "upper-disc (motor-side) encoder angle (rad, quantized)",
    "theta_l": "lower-disc encoder angle (rad, quantized)",
    "x": "LVDT x of the lower disc centre, fixed frame (m)",
    "y": "LVDT y of the lower disc centre, fixed frame (m)",
    "omega_ref": "target speed of the lower disc (rad/s)",
}
"""Measurement names a controller may read (see :attr:`Controller.uses`)."""

Measurement = Mapping[str, "float | np.ndarray"]


class Controller(ABC):
    """Base class of the controllers: reset, then one voltage per control period.

    A subclass sets :attr:`name` and :attr:`uses` and implements ``_act`` (and ``_reset`` when it has
    state); :meth:`act` clips its voltage to [-u_max, u_max].  Measurements are a mapping
    ``name -> value`` (:data:`MEASUREMENTS`), scalars for one rig or (n,) arrays for n rigs.

    Parameters
    ----------
    omega_ref : float or ndarray, optional
        Target lower-disc speed (rad/s), scalar or one per trajectory; a measurement ``omega_ref`` given to
        :meth:`reset` overrides it.
    config : str or Configuration, optional
        Rig configuration the controller is designed for ('torsional', 'coupled', ...).
    params : RigParams, optional
        The model the controller is designed on (default: the identified set; a model with effects is taken
        as ``model``).  The plant may differ
        (parameter-mismatch scenarios); the controller never sees the truth.
    model : drillgym.Model or path, optional
        A model with effects (a :class:`drillgym.Model` or its file), instead of ``params``.  A controller
        whose :attr:`uses_effects` is False refuses a model with effects, naming the first; a model-based one
        leaves out the effects of the lateral motion alone (with a warning) and refuses, naming it and why, an
        effect its model cannot represent (:func:`controllers.model.torsional_part`).
    dt : float, optional
        Control period (s); default :attr:`default_dt` of the class (10 ms; the observer samples the encoder at
        500 Hz).
    u_max : float, optional
        Voltage limit (V), the amplifier's range.
    """

    name: ClassVar[str] = "controller"
    uses: ClassVar[tuple[str, ...]] = ()
    default_dt: ClassVar[float] = DEFAULT_CONTROL_DT
    """Control period (s) when none is given: the period the controller is designed and evaluated at."""
    uses_effects: ClassVar[bool] = False
    """Whether the controller's own model runs the effects of the model it is built on."""

    def __init__(
        self,
        omega_ref: float | np.ndarray | None = None,
        *,
        config: str | Configuration = "torsional",
        params: RigParams | None = None,
        dt: float | None = None,
        u_max: float = U_MAX,
        model=None,
    ) -> None:
        dt = type(self).default_dt if dt is None else real_number("dt", dt, "s")
        u_max = real_number("u_max", u_max, "V")
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"control period dt must be a positive number of seconds, got {dt!r}")
        if not (np.isfinite(u_max) and u_max > 0):
            raise InputError(f"u_max must be a positive voltage, got {u_max!r}")
        self.config = parse_configuration(config)
        if not self.config.has_lower:
            raise InputError(f"controllers act on the lower disc; configuration {self.config.label!r} has none")
        from .model import model_of

        if params is not None and not isinstance(params, RigParams) and model is None:
            model, params = params, None  # a model (drillgym.Model) given where params are expected
        self.effects = model_of(model, params)
        """The model the controller is built on (a :class:`drillgym.Model`)."""
        if self.effects.composition.effects:
            if not self.uses_effects:
                raise InputError(
                    f"controller {self.name!r} is built on base parameters only and cannot use the model's effect "
                    f"{self.effects.composition.names[0]!r}; give it the base parameters (a model without effects)"
                )
            from .model import torsional_part

            self.effects = torsional_part(self.effects, f"controller {self.name!r}", self.uses)
        self.params = self.effects.params
        self.dt = float(dt)
        self.u_max = float(u_max)
        self._omega_ref_default = None if omega_ref is None else _check_ref(omega_ref)
        self.omega_ref = np.zeros(1)
        self.u_prev = np.zeros(1)
        self.n = 0

    # -- public API ----------------------------------------------------------
    def reset(self, measurement: Measurement | None = None) -> None:
        """Start an episode: batch size and target speed from ``measurement`` (or the constructor).

        Parameters
        ----------
        measurement : mapping of str to float or ndarray, optional
            The first measurements (:data:`MEASUREMENTS`, SI units): their size sets the number of rigs
            n; an ``omega_ref`` entry (rad/s) overrides the constructor's target.

        Raises
        ------
        InputError
            No target speed given, or a target that is not a positive finite speed.
        """
        m = dict(measurement or {})
        self._scalar = all(np.ndim(v) == 0 for v in m.values())
        n = max([np.size(v) for v in m.values()] + [1])
        if "omega_ref" in m:
            ref = _check_ref(m["omega_ref"])
        elif self._omega_ref_default is not None:
            ref = self._omega_ref_default
        else:
            raise InputError(
                f"controller {self.name!r} needs a target speed: pass omega_ref= or a measurement 'omega_ref'"
            )
        n = max(n, np.size(ref))
        self.n = n
        self.omega_ref = np.array(np.broadcast_to(ref, (n,)), dtype=float)
        self.u_prev = np.zeros(n)
        self._reset(self._arrays(m, check=False))

    def act(self, measurement: Measurement) -> float | np.ndarray:
        """Voltage to hold for the next control period.

        Parameters
        ----------
        measurement : mapping of str to float or ndarray
            The measurements named in :attr:`uses` (:data:`MEASUREMENTS`, SI units), scalars or (n,) arrays.

        Returns
        -------
        float or ndarray
            Voltage (V) in [-u_max, u_max]: a float for scalar measurements, else (n,).

        Raises
        ------
        InputError
            A measurement the controller uses is missing.
        """
        if self.n == 0:
            raise RuntimeError(f"controller {self.name!r}: call reset() before act()")
        u = np.clip(np.broadcast_to(self._act(self._arrays(measurement)), (self.n,)), -self.u_max, self.u_max)
        if not np.all(np.isfinite(u)):
            raise FloatingPointError(f"controller {self.name!r} produced a non-finite voltage")
        self.u_prev = np.array(u, dtype=float)
        return float(u[0]) if self._scalar else self.u_prev.copy()

    __call__ = act

    def reset_rigs(self, index: np.ndarray, measurement: Measurement) -> None:
        """Restart the rigs ``index`` only (e.g. those of a batch whose episode just ended), the others untouched.

        Parameters
        ----------
        index : ndarray of int
            The rigs (rows of the batch of :meth:`reset`) that start again from rest.
        measurement : mapping of str to float or ndarray
            The rigs' first measurements, (n,) arrays over the whole batch (rows ``index`` are read): those in
            :attr:`uses` and optionally ``omega_ref`` (rad/s, their new targets).

        Raises
        ------
        InputError
            Called before :meth:`reset`, or a new target that is not a positive finite speed (or one the
            controller was not designed for).
        NotImplementedError
            The controller cannot restart single rigs of a batch.
        """
        if self.n == 0:
            raise InputError(f"controller {self.name!r}: reset() the batch before reset_rigs()")
        index = np.asarray(index, dtype=np.int64)
        m = self._arrays(measurement, check=False)
        if "omega_ref" in m:
            ref = _check_ref(m["omega_ref"][index])
            self._check_new_targets(ref)
            self.omega_ref[index] = ref
        self.u_prev[index] = 0.0
        self._restart_rigs(index, m)

    def compiled_law(self):
        """The controller's law as compiled code, started from its current state (call after :meth:`reset`).

        The compiled closed loop (:func:`controllers.evaluation.runner.run_closed_loop`) then runs it for the
        whole batch with no Python call per control period.  A subclass offers one by defining
        :meth:`_compiled_law` beside the :meth:`_act` it compiles; a subclass that changes :meth:`_act` and keeps
        an ancestor's compiled law gets None here (that law computes the ancestor's commands, not its own), so
        the loop calls its :meth:`act` every period.

        Returns
        -------
        controllers.compiled.CompiledLaw or None
            The law, its state and constants; None when the controller (or its present settings) has none.
        """
        return self._compiled_law() if _law_compiles_act(type(self)) else None

    def _compiled_law(self):
        """The compiled law of the :meth:`_act` defined beside it (None: none; see :meth:`compiled_law`)."""
        return None

    def describe(self) -> str:
        """One line: what the controller is and which measurements it reads."""
        doc = (type(self).__doc__ or "").strip().splitlines()[0]
        return f"{self.name}: {doc} (reads: {', '.join(self.uses) or 'nothing'})"

    def approach_time(self, omega_ref: float | np.ndarray) -> np.ndarray:
        """Time from reset until the approach to each target is over and the controller holds it.

        An evaluation whose steady window starts earlier judges a transient.

        Parameters
        ----------
        omega_ref : float or ndarray
            Target speed(s) (rad/s).

        Returns
        -------
        ndarray
            Approach time (s) per target, shaped as ``omega_ref`` (0: at once).
        """
        return np.zeros(np.shape(np.asarray(omega_ref, dtype=float)))

    # -- for subclasses --------------------------------------------------------
    def _reset(self, m: dict[str, np.ndarray]) -> None:  # noqa: B027 - optional hook, stateless controllers keep it
        """Reset internal state; ``m`` holds the measurements given to :meth:`reset` as (n,) arrays.

        A hook: the default does nothing, for controllers without internal state.
        """

    def _check_new_targets(self, ref: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Refuse (InputError) new targets (rad/s) given to :meth:`reset_rigs` that the controller cannot
        hold; a hook: the default accepts every positive finite speed."""

    def _restart_rigs(self, index: np.ndarray, m: dict[str, np.ndarray]) -> None:
        """Restart the internal state of the rigs ``index`` from the measurements ``m`` ((n,) arrays); their
        targets and last voltages are already reset by :meth:`reset_rigs`."""
        raise NotImplementedError(f"controller {self.name!r} cannot restart single rigs of a batch")

    @abstractmethod
    def _act(self, m: dict[str, np.ndarray]) -> np.ndarray:
        """Voltage (n,) from measurements as (n,) arrays (clipping is done by :meth:`act`)."""

    def _arrays(self, measurement: Measurement, check: bool = True) -> dict[str, np.ndarray]:
        out = {}
        for k, v in measurement.items():
            a = np.asarray(v, dtype=float)
            out[k] = np.broadcast_to(a, (self.n,)) if a.ndim == 0 else a
        if check:
            missing = [k for k in self.uses if k not in out]
            if missing:
                raise InputError(f"controller {self.name!r} needs measurement(s) {missing}; got {sorted(out)}")
        return out


def _check_ref(ref: float | np.ndarray) -> np.ndarray:
    if ref is None or isinstance(ref, (str, bytes, bool)):
        raise InputTypeError(f"omega_ref must be a speed or an array of speeds (rad/s), got {ref!r}")
    try:
        r = np.atleast_1d(np.asarray(ref, dtype=float))
    except (TypeError, ValueError):
        raise InputTypeError(f"omega_ref must hold speeds (rad/s), got {ref!r}") from None
    if not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise InputError(f"omega_ref must be positive finite speeds (rad/s), got {ref!r}")
    return r


def _defined_by(cls: type, name: str) -> type:
    """The class of ``cls``'s method resolution order whose body defines ``name``."""
    return next(c for c in cls.__mro__ if name in vars(c))


def _law_compiles_act(cls: type) -> bool:
    """Whether the compiled law ``cls`` inherits was written for the ``_act`` it runs: the class defining
    ``_compiled_law`` is the one defining ``_act`` or derives from it."""
    return issubclass(_defined_by(cls, "_compiled_law"), _defined_by(cls, "_act"))
