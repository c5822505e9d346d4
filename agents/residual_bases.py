"""The classical controllers a residual policy can correct, by name: ``base: NAME`` in a recipe.

A residual base is a batched, model-based controller whose voltage the policy corrects by ``scale * a`` (V),
``a`` in [-1, 1]; with ``a = 0`` it is that controller.  Each has the interface the training wrapper
(:class:`agents.residual_base_env.ResidualBaseVecEnv`) and the deployed policy
(:class:`agents.controller.AgentController`) call: ``uses`` (the encoder readings it takes, by name), ``dim``,
``start(n)``, ``reset(index, omega_ref=..., **readings)``, ``correct(index=..., **readings)``, ``base()``,
``features()``, ``voltage(a)``, ``predict(u)``.

* ``observer``: :class:`agents.observer_residual.ObserverResidual`, on the motor encoder;
* ``lqg-2enc``: :class:`agents.two_encoder_residual.TwoEncoderResidual`, on both encoders.
"""

from __future__ import annotations

from typing import Any

from drillgym import RigParams
from drillgym.errors import InputError

from .observer_residual import ObserverResidual
from .two_encoder_residual import TwoEncoderResidual

__all__ = ["RESIDUAL_BASES", "make_residual_base"]

#: controller name -> its residual base class
RESIDUAL_BASES: dict[str, type] = {"observer": ObserverResidual, "lqg-2enc": TwoEncoderResidual}


def make_residual_base(
    name: str,
    config: str,
    scale: float,
    params: RigParams | None = None,
    dt: float = 0.01,
    options: dict[str, Any] | None = None,
    model: Any = None,
) -> ObserverResidual | TwoEncoderResidual:
    """The residual base of controller ``name``.

    Parameters
    ----------
    name : str
        A key of :data:`RESIDUAL_BASES`.
    config : str
        Rig configuration the controller is designed for.
    scale : float
        Voltage of a full action (V), > 0.
    params : RigParams, optional
        The design model's base parameters (default: the identified set); unused with ``model``.
    dt : float, optional
        Control period (s).
    options : dict, optional
        Keywords of the controller.
    model : drillgym.Model or str or path, optional
        The design model with its effects: the base is the controller ``controllers.make(name, model=...)``
        builds.

    Returns
    -------
    ObserverResidual or TwoEncoderResidual

    Raises
    ------
    InputError
        An unknown name, a bad scale, or options the controller refuses.
    """
    if name not in RESIDUAL_BASES:
        raise InputError(f"base must be {' or '.join(map(repr, RESIDUAL_BASES))}, got {name!r}")
    return RESIDUAL_BASES[name](config, scale, params, dt, options, model)
