"""The rig model of the equilibria (base parameters and effects), the equilibria's types and state names."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..configurations import Configuration, parse_configuration
from ..effects.base import Force, Measurement
from ..effects.composition import Composition, compose
from ..errors import InputError
from ..params import RigParams


class RigModel:
    """A rig model: base parameters, a composition of effects and the effects' values (picklable).

    Every function of this module and of :mod:`drillgym.bifurcation` takes one where it takes
    ``params``: ``RigModel(RigParams(), ["motor_lag"], {"tau_m": 0.02})``.

    Parameters
    ----------
    params : RigParams, optional
        Base parameters; default the identified set.
    effects : optional
        Effects (names, file specs, classes or instances, :mod:`drillgym.effects`).
    effect_params : mapping of str to float, optional
        The effects' parameter values by name.
    """

    def __init__(self, params: RigParams | None = None, effects=None, effect_params=None) -> None:
        self.params = params or RigParams()
        self.comp, self.values = compose(effects, effect_params)
        self.p = self.comp.vector(self.params, self.values)
        self.model = self.comp.kernels.model
        self.n_state = self.comp.n_state
        self.dy = np.zeros(self.n_state)
        self.fric = np.zeros(2)
        #: the composition changes the equations (not only what the sensors read)
        self.dynamic_effects = any(not issubclass(e, Measurement) for e in self.comp.effects)
        self.has_forces = any(issubclass(e, Force) for e in self.comp.effects)

    def __reduce__(self):
        return (RigModel, (self.params, self.comp, self.values))

    @property
    def composition(self) -> Composition:
        """The composition of effects."""
        return self.comp

    def f(self, y: np.ndarray, mode: np.ndarray, u: float, cfg: Configuration, t: float = 0.0) -> np.ndarray:
        """The compiled right-hand side at (t, y) in the friction modes ``mode``."""
        self.model.state_derivative(t, y, mode, float(u), self.p, int(cfg), 0.0, self.dy, self.fric)
        return self.dy.copy()

    def zero_state(self) -> np.ndarray:
        """A zero state vector of the model's length (8 + the effects' states)."""
        return np.zeros(self.n_state)


def as_model(params: RigParams | RigModel | None = None, effects=None, effect_params=None) -> RigModel:
    """A RigModel from RigParams (+ effects), or a RigModel itself.

    Parameters
    ----------
    params : RigParams or RigModel, optional
        Base parameters (default the identified set) or a model, returned as it is.
    effects : optional
        Effects of a new model.
    effect_params : mapping of str to float, optional
        Their parameter values by name.

    Returns
    -------
    RigModel
        The model.
    """
    if isinstance(params, RigModel):
        return params
    return RigModel(params, effects, effect_params)


def model_or_params(
    params: RigParams | RigModel | None = None, model=None, who: str = "bifurcation", configuration: str | None = None
) -> RigModel:
    """The RigModel of a call given ``params`` or ``model=`` (a :class:`drillgym.Model` or a model file's path).

    Parameters
    ----------
    params : RigParams or RigModel, optional
        Base parameters or a model with effects (default the identified set), when no ``model`` is given.
    model : drillgym.Model, str or path, optional
        The rig's model (read without ``trust`` when a path): its base parameters, effects and values.
    who : str, optional
        The function, in error messages.
    configuration : str, optional
        The run's configuration label: the model's effects that do not act there are left out, each with a
        warning (:meth:`drillgym.Model.in_configuration`).

    Returns
    -------
    RigModel
        The model.

    Raises
    ------
    InputError
        ``model`` given beside ``params`` (the model holds its own).
    """
    if model is None:
        return as_model(params)
    from ..model import model_arguments

    p, comp, values = model_arguments(model, params, None, None, who, configuration)
    return RigModel(p, comp, values)


def supported_configuration(
    config: str | Configuration, params: RigParams | RigModel | None = None, effects=None, effect_params=None
) -> Configuration:
    """Parse ``config`` and check that equilibria are defined for it (else ValueError)."""
    cfg = parse_configuration(config)
    if cfg is Configuration.FREE_VIBRATION:
        raise InputError("equilibria are defined for upper, torsional, lateral and coupled, not free_vibration")
    return cfg


# --------------------------------------------------------------------- states
def state_names(
    config: str | Configuration,
    variant: str = "reduced",
    params: RigParams | RigModel | None = None,
    effects=None,
    effect_params=None,
) -> list[str]:
    """Names of the linearisation's states for ``config`` and ``variant`` ('reduced' or 'angles')."""
    cfg = parse_configuration(config)
    if variant not in ("reduced", "angles"):
        raise InputError(f"variant must be 'reduced' or 'angles', got {variant!r}")
    if cfg is Configuration.UPPER:
        names = ["omega_u"] if variant == "reduced" else ["theta_u", "omega_u"]
    else:
        names = (
            ["alpha", "omega_u", "omega_l"] if variant == "reduced" else ["theta_u", "theta_l", "omega_u", "omega_l"]
        )
        if cfg.lateral_free:
            names += ["x", "y", "vx", "vy"]
    rig = as_model(params, effects, effect_params) if (effects is not None or isinstance(params, RigModel)) else None
    if rig is not None:
        names += list(rig.comp.state_names)
    return names


_MECH_INDEX = {"theta_u": 0, "theta_l": 1, "omega_u": 2, "omega_l": 3, "x": 4, "y": 5, "vx": 6, "vy": 7}


def state_index(name: str, comp: Composition) -> int:
    """Index of a mechanical or effect state ``name`` in the simulator's state vector."""
    return _MECH_INDEX[name] if name in _MECH_INDEX else 8 + comp.state_index(name)


def to_full_state(z: np.ndarray, names: Sequence[str], base: np.ndarray, comp: Composition) -> np.ndarray:
    """The simulator state ``base`` with the linearisation's states ``z`` (named ``names``) set in it."""
    y = base.copy()
    for v, n in zip(z, names):
        if n == "alpha":
            y[0] = 0.0
            y[1] = v
        else:
            y[state_index(n, comp)] = v
    return y


def from_full_derivative(dy: np.ndarray, names: Sequence[str], comp: Composition) -> np.ndarray:
    """The derivative of the linearisation's states ``names`` from the simulator's derivative ``dy``."""
    return np.array([dy[1] - dy[0] if n == "alpha" else dy[state_index(n, comp)] for n in names])


@dataclass(frozen=True)
class Equilibrium:
    """A slip equilibrium: both discs at speed ``omega`` (rad/s) under voltage ``u`` (V).

    ``alpha`` is the winding theta_l - theta_u (rad); ``x``, ``y`` the whirl
    position of the lower disc centre in the co-rotating frame (m; 0 when the
    disc is held); ``effect_states`` the equilibrium values of the effects' states.
    ``eigenvalues`` (1/s) are those of the reduced linearisation.
    """

    config: Configuration
    u: float
    omega: float
    alpha: float
    x: float = 0.0
    y: float = 0.0
    params: RigParams = field(default_factory=RigParams, repr=False, compare=False)
    eigenvalues: np.ndarray = field(default=None, repr=False, compare=False)
    effect_states: tuple = field(default=(), repr=False, compare=False)
    rig: RigModel | None = field(default=None, repr=False, compare=False)

    @property
    def r(self) -> float:
        """Radial whirl amplitude sqrt(x^2 + y^2) (m)."""
        return math.hypot(self.x, self.y)

    @property
    def modes(self) -> np.ndarray:
        """Friction modes (upper, lower) of the equilibrium: slipping in the direction of omega."""
        d = 1 if self.omega > 0 else -1
        return np.array([d, d if self.config is not Configuration.UPPER else 0], dtype=np.int64)

    @property
    def model(self) -> RigModel:
        """The RigModel of the equilibrium (its effects included)."""
        return self.rig if self.rig is not None else RigModel(self.params)

    @property
    def state(self) -> np.ndarray:
        """Full simulator state (theta_u = 0, theta_l = alpha; then the effects' states)."""
        y = np.zeros(8 + len(self.effect_states))
        y[1] = self.alpha if self.config is not Configuration.UPPER else 0.0
        y[2] = self.omega
        y[3] = self.omega if self.config is not Configuration.UPPER else 0.0
        y[4], y[5] = self.x, self.y
        y[8:] = self.effect_states
        return y

    @property
    def stable(self) -> bool:
        """Locally asymptotically stable (all eigenvalues in the open left half plane)."""
        return bool(np.max(self.eigenvalues.real) < 0.0)

    def to_dict(self) -> dict:
        """JSON-ready summary: kind, u (V), omega (rad/s), alpha (rad), x, y, r (m), stability."""
        return {
            "kind": "slip",
            "u": self.u,
            "omega": self.omega,
            "alpha": self.alpha,
            "x": self.x,
            "y": self.y,
            "r": self.r,
            "stable": self.stable,
            "max_real_eigenvalue": float(np.max(self.eigenvalues.real)),
        }


@dataclass(frozen=True)
class StickSet:
    """The stick equilibrium set at voltage ``u`` (V): both discs at rest, winding in [alpha_lo, alpha_hi] (rad)."""

    u: float
    alpha_lo: float
    alpha_hi: float

    def to_dict(self) -> dict:
        """JSON-ready summary: kind, u (V), omega = 0, alpha_lo, alpha_hi (rad), stable."""
        return {
            "kind": "stick",
            "u": self.u,
            "omega": 0.0,
            "alpha_lo": self.alpha_lo,
            "alpha_hi": self.alpha_hi,
            "stable": True,
        }
