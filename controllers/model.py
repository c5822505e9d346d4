"""The model a controller is built on (a :class:`drillgym.Model`) and what the controllers need of it.

A model-based controller (``observer``, ``lqg``, ``lqg-2enc``) runs the model it is given, every effect
included, through the composition's compiled kernels: :class:`controllers.dynamics.ModelDynamics` evaluates
and linearises the composition's right-hand side (every Force, Friction on either disc, Input effects with or
without states), the Delay effects become a line of past commands (the delay the composition's compiled
``hk_delay`` gives, split into whole control periods and a fraction, discretised exactly:
:func:`delayed_discretisation`), the Measurement effects on a channel the controller reads enter its output
map, and a static Input map that is monotone (a dead zone, an offset) is inverted in the command.

The controllers' model has no lateral motion: a model's effects of the lateral motion alone (a lateral force,
an effect acting only in the lateral and coupled configurations) are left out with a warning naming them, as the
base model's lateral motion is (:func:`torsional_part`); an effect that acts neither in the torsional configuration
nor on the lateral motion alone is refused in one line naming it and the reason.  A friction effect that depends
on time (``friction_drift``: the level drifts from the recording's start) has no origin in a controller's run: it
is evaluated at t = 0 (where the drift is neutral) and the disturbance state takes the drift; building such a
controller warns, naming it.

    >>> m = model_of("model.json")          # a drillgym.Model
    >>> motor_lag(m), input_delay(m)         # s, s
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import expm

from drillgym import RigParams
from drillgym.effects.base import Force, Input, Measurement
from drillgym.errors import InputError
from drillgym.model import Model

__all__ = [
    "Model",
    "model_of",
    "torsional_part",
    "motor_lag",
    "input_delay",
    "delayed_discretisation",
    "DelayedSystem",
]


def model_of(model: Any = None, params: RigParams | None = None) -> Model:
    """The controller's model from what a caller gives.

    Parameters
    ----------
    model : drillgym.Model, str or path, optional
        A model or a model file's path
        (:meth:`drillgym.Model.load`); None: ``params`` without effects.
    params : RigParams, optional
        Base parameters when no model is given (default: the identified set); refused together with a
        model (which has its own).

    Returns
    -------
    drillgym.Model
        The model.
    """
    if model is None:
        return Model(params or RigParams())
    if isinstance(model, Model):
        if params is not None and params != model.params:
            raise InputError("give the controller's base parameters either as params or in its model, not both")
        return model
    if params is not None:
        raise InputError("give the controller's base parameters either as params or in its model, not both")
    if isinstance(model, str) or hasattr(model, "__fspath__"):
        return Model.load(model)
    raise InputError(f"a controller's model is a drillgym.Model or a model file's path, not {type(model).__name__}")


#: the channels a controller may read, as Measurement effects name them
_READS = {"theta_u": "theta_u", "theta_l": "theta_l", "x": "X", "y": "Y"}


def torsional_part(model: Model, who: str, reads: Sequence[str] = ("theta_u",)) -> Model:
    """The part of the model the controllers' torsional model runs: an effect of the lateral motion alone is left
    out with a warning naming it, as the lateral motion itself is; one it cannot represent otherwise is refused in
    one line naming it and why.

    The controllers' model has no lateral motion: in the coupled configuration they are built on the torsional
    dynamics and leave out the base model's lateral degrees of freedom (its stiffness, damping, unbalance).  A force
    on the lower disc's centre, or an effect acting only where the disc moves laterally (an anisotropy of its
    support), changes what they leave out, not what they model.

    Parameters
    ----------
    model : drillgym.Model
        The model.
    who : str
        The controller, for the messages (``"controller 'observer'"``).
    reads : sequence of str
        The measurements it reads.

    Returns
    -------
    drillgym.Model
        ``model``, or the model without its effects of the lateral motion alone.

    Raises
    ------
    InputError
        An effect that acts neither in the torsional configuration nor on the lateral motion alone.
    """
    del reads  # every Measurement effect on a read channel enters the output map
    lateral_only = []
    for e in model.composition.effects:
        acts = tuple(e.configurations or ())
        if issubclass(e, Force) and e.acts_on == "lateral":
            lateral_only.append(e)
        elif acts and "torsional" not in acts and not issubclass(e, Measurement):
            if set(acts) <= {"lateral", "coupled"}:
                lateral_only.append(e)
            else:
                raise InputError(
                    f"{who} cannot use the model's effect {e.name!r} (it acts only in {', '.join(acts)}, not in the "
                    "controllers' torsional model)"
                )
        elif any("t" in e.argument_names(f) for f in e.defined_functions()):
            warnings.warn(
                f"{who}: the model's effect {e.name!r} depends on time; its model takes it at t = 0 and the "
                "disturbance state estimates its drift",
                stacklevel=3,
            )
    if not lateral_only:
        return model
    names = ", ".join(e.name for e in lateral_only)
    warnings.warn(
        f"{who} leaves out the model's effects of the lateral motion ({names}): its model has no lateral motion",
        stacklevel=3,
    )
    kept = tuple(e for e in model.composition.effects if e not in lateral_only)
    own = {p.name for e in kept for p in e.parameters}
    return Model(
        model.params,
        kept,
        {k: v for k, v in model.values.items() if k in own},
        {k: v for k, v in model.std.items() if k in own},
        model.provenance,
    )


def motor_lag(model: Model) -> float:
    """Time constant (s) of the first declared first-order lag on the command; 0 without one."""
    for e in model.composition.effects:
        if issubclass(e, Input) and e.lag:
            return float(model.values[next(iter(e.lag.values()))])
    return 0.0


def input_delay(model: Model) -> float:
    """Transport delay of the command (s): the composition's compiled ``hk_delay``; 0 without a Delay effect."""
    return model.composition.delay(model.vector)


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
