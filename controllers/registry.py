"""Controllers by name: ``controllers.make("observer", config="torsional", omega_ref=3.0)``.

Names: ``baseline``, ``pi``, ``descent`` (approach from above along the stable branch), ``softtorque``, ``observer`` (designed for a rig equal to its model),
``observer-robust`` (the same structure built to hold on a rig that differs from its model), ``lqg``,
``lqg-2enc`` (LQG on the motor and lower encoders), and
``agent:PATH`` for a trained policy.  ``NAME@MS`` runs a controller at another
control period (ms), e.g. ``observer@10`` for the observer at the environments'
10 ms instead of its 2 ms (the harness compares controllers at equal rates that way).  Agents plug in through one documented
callable, registered by the agents package (or anyone) with
:func:`register_agent_loader`::

    def load(path: str, *, config: str, omega_ref, params, dt: float, **kw) -> controllers.Controller: ...

The returned object is a :class:`controllers.Controller` (it reads the
measurements of :data:`controllers.base.MEASUREMENTS`, builds its own
observation from them and returns volts), so the evaluation harness, the
Gymnasium adapter and ``drillgym rig run`` treat it like any controller.  When
no loader is registered, ``agents.load_controller`` is tried.
"""

from __future__ import annotations

import importlib
from typing import Callable

from .base import Controller
from .baseline import BaselineController
from .observer import LQGController, ObserverController
from .pi import PIController
from .robust_observer import RobustObserverController
from .descent import DescentController
from .softtorque import SoftTorqueController
from .two_encoder import TwoEncoderLQG

__all__ = ["CONTROLLERS", "make", "available", "split_period", "register_agent_loader", "AgentLoader"]

CONTROLLERS: dict[str, type[Controller]] = {
    c.name: c for c in (BaselineController, PIController, DescentController, SoftTorqueController, RobustObserverController,
                        ObserverController, LQGController, TwoEncoderLQG)
}

AgentLoader = Callable[..., Controller]
_agent_loader: AgentLoader | None = None


def register_agent_loader(loader: AgentLoader) -> None:
    """Install the callable that turns ``agent:PATH`` into a Controller (see the module doc)."""
    global _agent_loader
    if not callable(loader):
        raise TypeError("agent loader must be callable")
    _agent_loader = loader


def available() -> list[str]:
    """Controller names accepted by :func:`make` (plus ``agent:PATH``)."""
    return sorted(CONTROLLERS)


def split_period(name: str) -> tuple[str, float | None]:
    """``'observer@10'`` -> ``('observer', 0.01)`` (control period in s); no ``@``: ``(name, None)``."""
    if name.startswith("agent:") or "@" not in name:
        return name, None
    base, _, ms = name.rpartition("@")
    try:
        dt = float(ms) * 1e-3
    except ValueError:
        raise ValueError(f"controller {name!r}: the period after '@' must be in ms, e.g. observer@10") from None
    if not (dt > 0 and dt < float("inf")):
        raise ValueError(f"controller {name!r}: the period after '@' must be a positive number of ms")
    return base, dt


def make(name: str, config: str = "torsional", omega_ref=None, params=None, **kw) -> Controller:
    """Build a controller by name (``agent:PATH`` for a trained policy, ``NAME@MS`` for another control
    period); ValueError names unknown ones."""
    name, dt = split_period(name)
    if dt is not None:
        if kw.get("dt") is not None and abs(kw["dt"] - dt) > 1e-12:
            raise ValueError(f"controller {name!r}: period {dt * 1e3:g} ms from the name but dt={kw['dt']} s given")
        kw["dt"] = dt
    if name.startswith("agent:"):
        path = name[len("agent:"):]
        if not path:
            raise ValueError("agent controller needs a path: agent:PATH")
        loader = _agent_loader
        if loader is None:
            try:
                loader = importlib.import_module("agents").load_controller
            except (ImportError, AttributeError) as exc:
                raise ValueError(f"no agent loader available for {name!r} (agents.load_controller): {exc}") from exc
        return loader(path, config=config, omega_ref=omega_ref, params=params, **kw)
    if name not in CONTROLLERS:
        raise ValueError(f"unknown controller {name!r}; choose from {', '.join(available())} or agent:PATH")
    return CONTROLLERS[name](omega_ref, config=config, params=params, **kw)
