"""Controllers by name: ``controllers.make("observer", config="torsional", omega_ref=3.0)``.

Names: ``baseline``, ``pi``, ``descent`` (approach from above along the stable branch),
``softtorque``, ``observer`` (designed for a rig equal to its model), ``observer-robust`` (the same
structure built to hold on a rig that differs from its model), ``lqg``, ``lqg-2enc`` (LQG on the
motor and lower encoders), and ``agent:PATH`` for a trained policy.  ``NAME@MS`` runs a controller
at another control period (ms), e.g. ``observer@10`` for the observer at the environments' 10 ms
instead of its 2 ms (the harness compares controllers at equal rates that way).  Agents plug in
through one documented callable, registered by the agents package (or anyone) with
:func:`register_agent_loader`::

    def load(path: str, *, config: str, omega_ref, params, dt: float, **kw) -> controllers.Controller: ...

The returned object is a :class:`controllers.Controller` (it reads the
measurements of :data:`controllers.base.MEASUREMENTS`, builds its own
observation from them and returns volts), so the evaluation harness, the
Gymnasium adapter and ``drillgym rig run`` treat it like any controller.  When
no loader is registered, the first installed entry point of the group
:data:`AGENT_LOADER_GROUP` (by name) is loaded: the ``agents`` package declares its
``agents:load_controller`` there (``pyproject.toml``), so this package never imports it.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import metadata

from drillgym.errors import InputError, InputTypeError

from .base import Controller
from .baseline import BaselineController
from .descent import DescentController
from .observer import LQGController, ObserverController
from .pi import PIController
from .robust_observer import RobustObserverController
from .softtorque import SoftTorqueController
from .two_encoder import TwoEncoderLQG

__all__ = [
    "CONTROLLERS",
    "make",
    "available",
    "split_period",
    "register_agent_loader",
    "AgentLoader",
    "AGENT_LOADER_GROUP",
]

CONTROLLERS: dict[str, type[Controller]] = {
    c.name: c
    for c in (
        BaselineController,
        PIController,
        DescentController,
        SoftTorqueController,
        RobustObserverController,
        ObserverController,
        LQGController,
        TwoEncoderLQG,
    )
}

AgentLoader = Callable[..., Controller]
#: entry-point group of the installed agent loaders (value: an :data:`AgentLoader`)
AGENT_LOADER_GROUP = "controllers.agent_loaders"
_agent_loader: AgentLoader | None = None


def register_agent_loader(loader: AgentLoader) -> None:
    """Install the callable that turns ``agent:PATH`` into a controller.

    Parameters
    ----------
    loader : callable
        ``loader(path, *, config, omega_ref, params, dt, **kw)`` returning a :class:`Controller`
        (see the module documentation). It replaces any loader installed before and the
        entry-point lookup.

    Raises
    ------
    InputTypeError
        ``loader`` is not callable.
    """
    global _agent_loader
    if not callable(loader):
        raise InputTypeError(f"agent loader must be callable, got {type(loader).__name__}")
    _agent_loader = loader


def _installed_agent_loader(name: str) -> AgentLoader:
    """The loader of the first entry point of :data:`AGENT_LOADER_GROUP` (by name)."""
    try:
        eps = sorted(metadata.entry_points(group=AGENT_LOADER_GROUP), key=lambda ep: ep.name)
    except TypeError:  # pragma: no cover - Python < 3.10 API
        eps = sorted(metadata.entry_points().get(AGENT_LOADER_GROUP, []), key=lambda ep: ep.name)
    if not eps:
        raise InputError(
            f"no agent loader available for {name!r}: install the agents package (its entry point "
            f"{AGENT_LOADER_GROUP}) or call controllers.register_agent_loader"
        )
    try:
        return eps[0].load()
    except ImportError as exc:
        raise InputError(
            f"no agent loader available for {name!r}: entry point {eps[0].value} does not load: {exc}"
        ) from exc


def available() -> list[str]:
    """Controller names accepted by :func:`make`.

    Returns
    -------
    list of str
        The registered names, sorted (``agent:PATH`` is accepted besides them).
    """
    return sorted(CONTROLLERS)


def split_period(name: str) -> tuple[str, float | None]:
    """Split a controller name from its control period.

    Parameters
    ----------
    name : str
        A controller name, optionally ``NAME@MS`` with the control period in ms.

    Returns
    -------
    tuple of (str, float or None)
        The name and the control period (s); ``(name, None)`` without ``@`` and for ``agent:PATH``.

    Raises
    ------
    InputError
        The period after ``@`` is not a positive finite number of ms.

    Examples
    --------
    >>> split_period("observer@10")
    ('observer', 0.01)
    """
    if name.startswith("agent:") or "@" not in name:
        return name, None
    base, _, ms = name.rpartition("@")
    try:
        dt = float(ms) * 1e-3
    except ValueError:
        raise InputError(f"controller {name!r}: the period after '@' must be in ms, e.g. observer@10") from None
    if not (dt > 0 and dt < float("inf")):
        raise InputError(f"controller {name!r}: the period after '@' must be a positive number of ms")
    return base, dt


def make(name: str, config: str = "torsional", omega_ref=None, params=None, **kw) -> Controller:
    """Build a controller by name.

    Parameters
    ----------
    name : str
        A name of :func:`available`, ``NAME@MS`` for another control period (ms), or
        ``agent:PATH`` for a trained policy (built by the agent loader, see the module documentation).
    config : str, optional
        Rig configuration the controller is built for. Default ``"torsional"``.
    omega_ref : float, optional
        Target lower-disc speed (rad/s); None lets the controller take it from the measurements.
    params : RigParams, optional
        The model the controller is designed on; default the nominal parameters.
    **kw
        ``model=``: a model with effects instead of ``params`` (a :class:`drillgym.Model` or a model file's
        path): ``observer``, ``lqg`` and ``lqg-2enc`` run every effect of
        it in their own model (:mod:`controllers.dynamics`); the others refuse a model with effects, and what a
        model-based controller cannot represent is refused in one line naming the effect and why.
        A model that knows its encoders (:attr:`drillgym.Model.encoders`: what the recording it was identified
        on showed) gives them as ``counts_per_rev`` and ``angle_noise`` to a controller that takes them, unless
        the call gives either.
        ``agent:PATH`` takes the model's base parameters only (for a residual or observer base; a plain
        network ignores the model, see ``agents.controller.AgentController``).
        Further keywords of the controller's constructor (e.g. ``dt``, the control period in s).

    Returns
    -------
    Controller
        The controller, not yet reset.

    Raises
    ------
    InputError
        The name is unknown, its period is malformed or contradicts ``dt``, ``agent:`` has no path,
        or no agent loader is available.
    """
    if not isinstance(name, str):
        raise InputTypeError(
            f"controller name must be a text (one of {', '.join(available())} or agent:PATH), got {name!r}"
        )
    name, dt = split_period(name)
    if dt is not None:
        if kw.get("dt") is not None and abs(kw["dt"] - dt) > 1e-12:
            raise InputError(f"controller {name!r}: period {dt * 1e3:g} ms from the name but dt={kw['dt']} s given")
        kw["dt"] = dt
    if name.startswith("agent:"):
        path = name[len("agent:") :]
        if not path:
            raise InputError("agent controller needs a path: agent:PATH")
        loader = _agent_loader if _agent_loader is not None else _installed_agent_loader(name)
        return loader(path, config=config, omega_ref=omega_ref, params=params, **kw)
    if name not in CONTROLLERS:
        raise InputError(f"unknown controller {name!r}; choose from {', '.join(available())} or agent:PATH")
    _with_encoders(CONTROLLERS[name], kw)
    _check_keywords(CONTROLLERS[name], name, kw)
    return CONTROLLERS[name](omega_ref, config=config, params=params, **kw)


def _with_encoders(cls: type, kw: dict) -> None:
    """The encoders of the model in ``kw`` (:attr:`drillgym.Model.encoders`, what its recording showed) as the
    controller's ``counts_per_rev`` and ``angle_noise``, where its constructor takes them and the caller gave
    neither; the model read once (a path becomes the Model)."""
    if kw.get("model") is None or "counts_per_rev" in kw or "angle_noise" in kw:
        return
    taken = _keywords(cls)
    if taken is None or "counts_per_rev" not in taken:
        return
    from drillgym import RigParams

    from .model import model_of

    if isinstance(kw["model"], RigParams):
        return
    kw["model"] = model_of(kw["model"])
    if kw["model"].encoders is not None:
        kw.update(kw["model"].encoders.controller_keywords())


def _keywords(cls: type) -> dict | None:
    """The keywords (name -> inspect.Parameter) of the controller's constructors along the class's bases for as
    long as each passes ``**kw`` on; None when every one does (nothing to tell)."""
    import inspect

    taken: dict[str, inspect.Parameter] = {}
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        params = inspect.signature(init).parameters
        for n, p in params.items():
            if n != "self" and p.kind not in (inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD):
                taken.setdefault(n, p)
        if not any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
            return taken
    return None


def _check_keywords(cls: type, name: str, kw: dict) -> None:
    """Refuse a keyword the controller's constructor does not take (naming it and those it takes), and a value
    that is not a number for a keyword whose default is one (:func:`_keywords`)."""
    taken = _keywords(cls)
    if taken is None:
        return
    unknown = sorted(set(kw) - set(taken))
    if unknown:
        raise InputError(
            f"controller {name!r} takes no keyword {', '.join(map(repr, unknown))}; it takes {', '.join(taken)}"
        )
    _check_numbers(taken, name, kw)


def _check_numbers(taken: dict, name: str, kw: dict) -> None:
    """Refuse a value that is not a number for a keyword whose default is one (``dt="0.01"``); None passes (some
    controllers take it to switch a part off)."""
    import numbers

    import numpy as np

    for key, value in kw.items():
        default = taken[key].default
        if isinstance(default, bool) or not isinstance(default, numbers.Real):
            continue
        if isinstance(value, np.ndarray) and value.ndim == 0:
            value = value.item()
        if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
            raise InputTypeError(f"controller {name!r}: {key} must be a number, got {value!r}")
