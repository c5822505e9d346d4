"""The model a controller is built on: base parameters and effects, as a model file holds them.

A model-based controller (``observer``, ``lqg``, ``lqg-2enc``) runs the model it is given, effects
included, through the composition's compiled kernels (:mod:`drillgym.effects`):

* an **Input** effect that declares one first-order lag state (``motor_lag``: tau_m du_m/dt = u - u_m)
  becomes a state of the controller's linear model (the motor torque is km u_m);
* **Delay** effects (``input_delay``) become a line of past commands: the delay the composition's
  compiled ``hk_delay`` gives, split into whole control periods and a fraction, discretised exactly
  (the motor sees the older command for the fraction of each period, :func:`delayed_discretisation`);
* **Friction** effects on the lower disc (``position_friction``, ``brake_asymmetry``, ``friction_drift``, a
  user's friction file) enter the brake law the controller uses: its torque, slope and stick set are
  the composition's compiled ``lower_slip_torque``/``lower_stick_bounds`` at the estimated lower angle
  and speed (the linearisation of the Kalman filter takes the slope in the speed at the estimated
  angle; the law's derivatives hold the angle fixed over a period: :mod:`controllers.observer`);
* **Measurement** effects on channels the controller does not read (the LVDT's) change nothing it uses.

A friction effect that depends on time (``friction_drift``: the level drifts from the recording's start)
has no origin in a controller's run: the controller's law evaluates it at t = 0 (where the drift is
neutral) and its disturbance state (the brake's estimated level or torque) takes the drift; building
such a controller warns, naming the effect.

Any other effect (an Input effect without a lag, a Force, a Friction on the upper disc, a
Measurement on an encoder the controller reads) is refused in one line that names it: a controller
never silently runs a model other than the one it is given.

    >>> from drillgym.identification.model_file import read_model
    >>> m = ControllerModel.from_model(read_model("identified.json"))
    >>> m.lag, m.delay                      # s, s
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import expm

from drillgym import RigParams
from drillgym.effects import Composition, compose
from drillgym.effects.base import Delay, Friction, Input, Measurement
from drillgym.errors import InputError
from drillgym.friction import lower_friction

__all__ = ["ControllerModel", "model_of", "delayed_discretisation", "DelayedSystem"]

#: the channels a controller may read, as Measurement effects name them
_READS = {"theta_u": "theta_u", "theta_l": "theta_l", "x": "X", "y": "Y"}


@dataclass(frozen=True)
class ControllerModel:
    """Base parameters, the effects' composition and values, and the standard errors identification gave.

    Parameters
    ----------
    params : RigParams
        Base parameters.
    composition : Composition
        The effects (default: none, the base model).
    values : mapping of str to float
        The effects' parameter values by name.
    std : mapping of str to float
        Standard errors by parameter name (base or effect; absent: unknown).
    """

    params: RigParams = field(default_factory=RigParams)
    composition: Composition = field(default_factory=lambda: compose(None)[0])
    values: Mapping[str, float] = field(default_factory=dict)
    std: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_model(cls, model: Any) -> ControllerModel:
        """From a :class:`~drillgym.identification.model_file.ModelFile` (``read_model``)."""
        comp, values = compose(list(model.specs), dict(model.values))
        return cls(model.params, comp, values, dict(getattr(model, "std", {}) or {}))

    @property
    def vector(self) -> np.ndarray:
        """The composition's parameter vector (base, then effect parameters)."""
        return self.composition.vector(self.params, self.values)

    @property
    def label(self) -> str:
        """``base`` or the effects joined by ``+``."""
        return self.composition.label

    def check_usable(self, who: str, reads: Sequence[str]) -> None:
        """Refuse, naming it, an effect that ``who`` (a controller reading ``reads``) cannot run in its model.

        Raises
        ------
        InputError
            An effect of a kind the controller's model has no place for (see the module doc).
        """
        seen = {n: _READS.get(n, n) for n in reads}
        lags = 0
        for e in self.composition.effects:
            why = ""
            if issubclass(e, Input):
                if len(e.states) != 1 or set(e.lag) != {e.states[0].name}:
                    why = "an input effect other than a first-order lag"
                lags += 1
            elif issubclass(e, Delay):
                continue
            elif issubclass(e, Friction):
                if e.disc != "lower":
                    why = f"friction on the {e.disc} disc"
                elif any("t" in e.argument_names(f) for f in e.defined_functions()):
                    warnings.warn(
                        f"{who}: the model's effect {e.name!r} depends on time; the law takes it at t = 0 and the "
                        "disturbance state estimates its drift",
                        stacklevel=3,
                    )
            elif issubclass(e, Measurement):
                hit = [c for c in e.channels if c in seen.values()]
                if hit:
                    why = f"a measurement effect on {', '.join(hit)}, which it reads"
            else:
                why = f"a {e.kind} effect"
            if lags > 1 and not why:
                why = "a second lag on the command"
            if why:
                raise InputError(
                    f"{who} cannot use the model's effect {e.name!r} ({why}); "
                    "it uses motor lags, delays, lower-disc friction and measurement effects off the channels it reads"
                )

    @property
    def lag(self) -> float:
        """Time constant (s) of the first-order lag on the command; 0 without one."""
        for e in self.composition.effects:
            if issubclass(e, Input) and e.lag:
                return float(self.values[next(iter(e.lag.values()))])
        return 0.0

    @property
    def delay(self) -> float:
        """Transport delay of the command (s): the composition's compiled ``hk_delay``; 0 without a Delay effect."""
        if not self.composition.has_delay:
            return 0.0
        return float(self.composition.kernels.hooks.hk_delay(self.vector))

    @property
    def friction_effects(self) -> bool:
        """True when a Friction effect changes the brake law (it then depends on the lower angle and time)."""
        return any(issubclass(e, Friction) and e.disc == "lower" for e in self.composition.effects)

    def lower_friction(self, w: np.ndarray, theta_l: np.ndarray | float = 0.0, t: float = 0.0) -> np.ndarray:
        """The model's brake torque (N m) while the lower disc slips at speeds ``w`` (rad/s, != 0) and angles
        ``theta_l`` (rad) at time ``t`` (s): the base law, then the composition's Friction effects."""
        w = np.asarray(w, dtype=float)
        if not self.friction_effects:
            return lower_friction(w, self.params)
        th = np.broadcast_to(np.asarray(theta_l, dtype=float), w.shape)
        f = _batch_kernels(self.composition)
        return f.slip(np.ascontiguousarray(w.ravel()), np.ascontiguousarray(th.ravel()), float(t), self.vector).reshape(
            w.shape
        )

    def stick_limit(self, theta_l: np.ndarray | float, t: float = 0.0) -> np.ndarray:
        """Largest torque (N m) the brake holds the resting disc with at angles ``theta_l`` (rad), time ``t`` (s)."""
        th = np.atleast_1d(np.asarray(theta_l, dtype=float))
        if not self.friction_effects:
            return np.full(th.shape, self.params.Ts)
        f = _batch_kernels(self.composition)
        return f.stick(np.ascontiguousarray(th.ravel()), float(t), self.vector).reshape(th.shape)


def model_of(model: Any = None, params: RigParams | None = None) -> ControllerModel:
    """The controller's model from what a caller gives.

    Parameters
    ----------
    model : ControllerModel, ModelFile, str or path, optional
        A model, a model file read (``read_model``) or its path; None: ``params`` without effects.
    params : RigParams, optional
        Base parameters when no model is given (default: the identified set); refused together with a
        model (which has its own).

    Returns
    -------
    ControllerModel
        The model.
    """
    if model is None:
        return ControllerModel(params or RigParams())
    if params is not None and not isinstance(model, ControllerModel):
        raise InputError("give the controller's base parameters either as params or in its model, not both")
    if isinstance(model, ControllerModel):
        return model
    if isinstance(model, (str,)) or hasattr(model, "__fspath__"):
        from drillgym.identification.model_file import read_model

        model = read_model(model)
    return ControllerModel.from_model(model)


# ---------------------------------------------------------------------------- compiled brake law, batched
_KERNELS: dict[Composition, Any] = {}


@dataclass(frozen=True)
class _BatchFriction:
    slip: Any
    stick: Any


def _batch_kernels(comp: Composition) -> _BatchFriction:
    """Batched calls of the composition's compiled ``lower_slip_torque`` and ``lower_stick_bounds`` (brake on),
    compiled once per composition and process."""
    if comp in _KERNELS:
        return _KERNELS[comp]
    from numba import njit

    slip_torque = comp.kernels.model.lower_slip_torque
    stick_bounds = comp.kernels.model.lower_stick_bounds
    ny = comp.n_state

    @njit(cache=False)
    def slip(w, thl, t, p):  # pragma: no cover - compiled
        out = np.empty(w.size)
        y = np.zeros(ny)
        for i in range(w.size):
            y[1] = thl[i]
            y[3] = w[i]
            out[i] = slip_torque(w[i], 1.0 if w[i] >= 0.0 else -1.0, t, y, p, True)
        return out

    @njit(cache=False)
    def stick(thl, t, p):  # pragma: no cover - compiled
        out = np.empty(thl.size)
        y = np.zeros(ny)
        for i in range(thl.size):
            y[1] = thl[i]
            out[i] = stick_bounds(t, y, p, True)[1]
        return out

    _KERNELS[comp] = _BatchFriction(slip, stick)
    return _KERNELS[comp]


# ---------------------------------------------------------------------------- delay as a line of commands
@dataclass(frozen=True)
class DelayedSystem:
    """x+ = Ad x + Bd u of a continuous system whose input ``u`` (column 0 of B) arrives ``delay`` later.

    The state is the system's, then the line of past commands (u[k-1], ..., u[k-L]); the other input
    columns are not delayed.  ``n_line`` = L.
    """

    Ad: np.ndarray
    Bd: np.ndarray
    n_line: int


def _zoh(A: np.ndarray, B: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{A tau}, int_0^tau e^{A s} ds B)."""
    n, m = A.shape[0], B.shape[1]
    M = expm(np.block([[A, B], [np.zeros((m, n + m))]]) * tau)
    return M[:n, :n], M[:n, n:]


def delayed_discretisation(A: np.ndarray, B: np.ndarray, dt: float, delay: float = 0.0) -> DelayedSystem:
    """Zero-order-hold discretisation with the first input delayed by ``delay`` (s), exactly.

    With delay = N dt + f (0 <= f < dt), over period k the system sees u[k-N-1] for the first f seconds and
    u[k-N] for the rest (Åström and Wittenmark, Computer-Controlled Systems, sec. 2.3).

    Parameters
    ----------
    A : ndarray
        (n, n) continuous system matrix.
    B : ndarray
        (n, m) input matrix; column 0 is the delayed command.
    dt : float
        Period (s).
    delay : float, optional
        Delay of input 0 (s), >= 0.

    Returns
    -------
    DelayedSystem
        The augmented discrete system (n + L states, m inputs).
    """
    if not (np.isfinite(delay) and delay >= 0):
        raise InputError(f"delay must be a non-negative time (s), got {delay!r}")
    n, m = A.shape[0], B.shape[1]
    Phi, G = _zoh(A, B, dt)
    N = int(np.floor(delay / dt + 1e-9))
    f = max(delay - N * dt, 0.0)
    if f < 1e-9 * dt:
        f = 0.0
    L = N + (1 if f > 0 else 0)
    if L == 0:
        return DelayedSystem(Phi, G, 0)
    b = B[:, :1]
    Pr, Gr = _zoh(A, b, dt - f)  # the newer command u[k-N], over the last dt - f seconds
    Gold = Pr @ _zoh(A, b, f)[1] if f > 0 else np.zeros((n, 1))  # u[k-N-1], the first f seconds
    Ad = np.zeros((n + L, n + L))
    Bd = np.zeros((n + L, m))
    Ad[:n, :n] = Phi
    Bd[:n, 1:] = G[:, 1:]
    if N == 0:
        Bd[:n, :1] = Gr
    else:
        Ad[:n, n + N - 1 : n + N] = Gr
    if f > 0:
        Ad[:n, n + N : n + N + 1] = Gold
    Bd[n, 0] = 1.0  # the line: u[k] enters, the rest shift by one
    for j in range(1, L):
        Ad[n + j, n + j - 1] = 1.0
    return DelayedSystem(Ad, Bd, L)
