"""The simulated plant of a command that runs a rig it does not tell the host about (``rig emulate``,
``evaluate``): base parameters from ``--params`` (RigParams, or a model file written by
``identify`` with its effects) plus hidden effects from ``--add-effect``/``--effect-param``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError
from .effect_options import check_effects_act, parse_effect_params

if TYPE_CHECKING:  # pragma: no cover - the effects and parameters (numpy) load when a command runs
    from ..configurations import Configuration
    from ..effects import Composition
    from ..params import RigParams

__all__ = ["plant_from_cli", "describe_plant"]


def plant_from_cli(
    params_file: Path | None,
    add_effect: list[str] | None,
    effect_param: list[str] | None,
    trust: bool = False,
    configs: Sequence[Configuration] = (),
) -> tuple[RigParams, Composition, dict[str, float]]:
    """(base RigParams, Composition, effect values): the base parameters and effects of ``params_file``
    (default: the identified set, no effect), then the ``add_effect`` specs, with the ``effect_param``
    NAME=VALUE items; one-line errors name the file, the effect and what is wrong.  An effect that does not act
    in one of ``configs`` (the plant would run without it, silently) is refused, naming the option it came from."""
    from ..model import Model
    from .effect_options import compose_named
    from .options import option

    with option("--params"):
        mf = Model.load(params_file, trust=trust) if params_file is not None else Model()
        for c in configs:
            mf.composition.refuse_not_acting(c.label, f"{params_file}: the model's effects")
    extra = parse_effect_params(effect_param)
    specs = list(mf.specs) + list(add_effect or [])
    if extra and not specs:
        raise InputError(f"--effect-param {next(iter(extra))}: no effect added (use --add-effect NAME)")
    comp, values = compose_named(specs, {**mf.values, **extra})
    for c in configs:  # the model file's effects act: what is left is an added one
        check_effects_act(comp, c)
    return mf.params, comp, values


def describe_plant(comp: Composition, values: Mapping[str, float]) -> str:
    """One line: ``hidden effects: input_delay(delay=0.03), ...`` or ``no hidden effects``."""
    if not comp.effects:
        return "no hidden effects"
    parts = []
    for e in comp.effects:
        vals = ", ".join(f"{p.name}={values[p.name]:g}" for p in e.parameters)
        parts.append(f"{e.name}({vals})" if vals else e.name)
    return "hidden effects: " + ", ".join(parts)
