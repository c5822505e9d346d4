"""Which base parameters act in which configuration: a fit only frees parameters the recording depends on.

A parameter that does not enter the configuration's equations (docs/model.md: the lateral stiffness ``k`` in
``torsional``, where the lateral motion is held; the brake's Stribeck law in ``lateral``, where the brake
is off) cannot be fitted from its recording: the fit would return its start value with a warning at
best. :func:`check_fit_names` refuses such a request in one line, naming the parameters that do act.
"""

from __future__ import annotations

from collections.abc import Iterable

from ..configurations import Configuration
from ..errors import InputError
from ..params import PARAM_INFO

__all__ = ["UPPER_PARAMETERS", "parameters_acting", "check_fit_names"]

#: the driven upper disc: inertia, motor constant, asymmetric Coulomb and viscous friction
UPPER_PARAMETERS = ("Ju", "km", "Tcu", "dTcu", "bu", "dbu")
_STRING = ("Jl", "ktheta")
_BEARING = ("Tcl", "bl")
_BRAKE = ("Ts", "Tc", "ws", "delta", "bb")
_LATERAL = ("mr", "mt", "k", "b", "e")


def parameters_acting(config: Configuration, brake: bool | None = None) -> tuple[str, ...]:
    """The base parameters that enter the equations of a configuration (docs/model.md).

    Parameters
    ----------
    config : Configuration
        The configuration.
    brake : bool, optional
        Override the configuration's brake (the staged identification's lower stage: the torsional
        system with the brake off). Default: the configuration's.

    Returns
    -------
    tuple of str
        The parameter names, in the order of :class:`drillgym.params.RigParams`.
    """
    if config is Configuration.UPPER:
        return UPPER_PARAMETERS
    if config is Configuration.FREE_VIBRATION:  # upper disc clamped, brake off, lateral motion held
        return _STRING + _BEARING
    brake = config.brake if brake is None else brake
    names = UPPER_PARAMETERS + _STRING + (_BRAKE if brake else _BEARING)
    return names + (_LATERAL if config.lateral_free else ())


def check_fit_names(names: Iterable[str], config: Configuration, option: str = "--fit", **kwargs) -> None:
    """Refuse base parameters that do not act in ``config`` (effect parameters pass: their effect is checked).

    Parameters
    ----------
    names : iterable of str
        The parameters asked to be fitted.
    config : Configuration
        The recording's configuration.
    option : str, optional
        The option or argument named in the message.
    **kwargs
        Passed to :func:`parameters_acting` (``brake``).

    Raises
    ------
    InputError
        ``"--fit k: the lateral stiffness does not act in configuration torsional; parameters that do: ..."``,
        or a parameter named twice.
    """
    names = list(names)
    twice = next((n for i, n in enumerate(names) if n in names[:i]), None)
    if twice is not None:
        raise InputError(f"{option} {twice}: given twice; name each parameter once")
    acting = parameters_acting(config, **kwargs)
    for n in names:
        if n in PARAM_INFO and n not in acting:
            raise InputError(
                f"{option} {n}: the {PARAM_INFO[n]['doc']} does not act in configuration {config.label} "
                f"(the recording cannot determine it); parameters that do: {', '.join(acting)}"
            )
