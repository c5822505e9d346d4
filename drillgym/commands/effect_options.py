"""The options every command that runs the model shares to add effects:
``--add-effect NAME`` / ``--add-effect path/to/file.py:NAME`` (repeatable) and
``--effect-param NAME=VALUE`` (repeatable, values of the added effects' parameters)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from ..errors import InputError

if TYPE_CHECKING:  # pragma: no cover - the effects (numpy) load when a command runs, not for its --help
    from ..effects.composition import Composition

ADD_EFFECT_HELP = (
    "effect added to the base model: a name (see `drillgym effects`) or path/to/file.py:NAME; repeat for several"
)
EFFECT_PARAM_HELP = "value of an added effect's parameter, NAME=VALUE (SI units); repeat for several"


def add_effect_option() -> list[str]:
    return typer.Option(None, "--add-effect", help=ADD_EFFECT_HELP)


def effect_param_option() -> list[str]:
    return typer.Option(None, "--effect-param", help=EFFECT_PARAM_HELP)


#: what ``--trust`` says: loading a model file imports the effect files it names
TRUST_HELP = (
    "import the effect files the model file names even when they lie outside its folder, carry no recorded "
    "hash or changed since it was written (an effect file is code: loading it runs it)"
)


def trust_option() -> bool:
    return typer.Option(False, "--trust", help=TRUST_HELP)


#: what ``--model FILE`` says on a command that runs the rig's model
MODEL_HELP = (
    "model file (JSON/YAML, drillgym.Model: base parameters and effects, e.g. what `drillgym identify` wrote) the "
    "run uses; not with --params, --add-effect or --effect-param (the model holds its own)"
)


def model_option(help: str = MODEL_HELP):
    return typer.Option(None, "--model", help=help)


def model_from_cli(model_file, trust: bool = False, config=None, **beside):
    """The :class:`drillgym.Model` of ``--model FILE`` (read with :meth:`drillgym.Model.load`, ``--trust``).

    Parameters
    ----------
    model_file : path
        The model file.
    trust : bool, optional
        ``--trust``: import effect files outside the model's folder, unhashed or changed.
    config : Configuration, optional
        The run's configuration: an effect of the model that does not act in it is left out, with a warning.
    **beside
        The options that name the model's parts, by option (``{"--params": value, ...}`` as keywords
        ``params=``, ``add_effect=``, ``effect_param=``): any of them given is refused in one line.

    Returns
    -------
    drillgym.Model
        The model.

    Raises
    ------
    InputError
        ``--model`` beside ``--params``, ``--add-effect`` or ``--effect-param``, or a file that cannot be used
        (the message leads with ``--model``).
    """
    from ..model import Model
    from .options import option

    given = ["--" + k.replace("_", "-") for k, v in beside.items() if v]
    if given:
        raise InputError(
            f"--model cannot go with {', '.join(given)} (the model file holds its base parameters and effects)"
        )
    with option("--model"):
        m = Model.load(model_file, trust=trust)
        if config is not None:  # an effect that does not act there is left out, with a warning
            m = m.in_configuration(config.label)
    return m


def parse_effect_params(items: list[str] | None) -> dict[str, float]:
    """``["tau_m=0.02", "c3=1.5"]`` -> {"tau_m": 0.02, "c3": 1.5}; a one-line error names a bad item (not
    NAME=VALUE, not a number, a name given twice: which value was meant is not for the tool to guess)."""
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise InputError(f"--effect-param {item!r}: expected NAME=VALUE, e.g. tau_m=0.02")
        if name.strip() in out:
            raise InputError(f"--effect-param {item!r}: {name.strip()!r} is given twice; give each parameter once")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise InputError(f"--effect-param {item!r}: {value!r} is not a number") from None
    return out


def check_effects_act(comp: Composition, config, option: str = "--add-effect") -> None:
    """Refuse an effect that does not act in ``config`` (it would change nothing, silently).

    Parameters
    ----------
    comp : Composition
        The effects.
    config : Configuration
        The configuration of the run or the recording.
    option : str, optional
        The option that named the effects, for the message.

    Raises
    ------
    InputError
        An effect whose ``configurations`` leave out ``config``.
    """
    comp.refuse_not_acting(config.label, option)


def compose_named(
    specs: list[str], values: dict[str, float], effect_option: str = "--add-effect"
) -> tuple[Composition, dict[str, float]]:
    """:func:`compose` whose errors name the option: a bad effect ``effect_option``, a bad value ``--effect-param``."""
    from ..effects.composition import compose
    from .options import option

    with option(effect_option):
        comp, defaults = compose(list(specs))  # an effect instance in a file brings its values
    with option("--effect-param"):
        return compose(comp, {**defaults, **values})


def rig_from_cli(model_file, trust: bool, config, params, add_effect, effect_param):
    """``(RigParams, Composition, effect values)`` of a run: the model of ``--model FILE`` (refused beside
    ``--params``/``--add-effect``/``--effect-param``), else ``--params`` with ``--add-effect``/``--effect-param``."""
    if model_file is not None:
        m = model_from_cli(model_file, trust, config, params=params, add_effect=add_effect, effect_param=effect_param)
        return m.params, m.composition, dict(m.values)
    from ..params import RigParams
    from .options import option

    comp, values = effects_from_cli(add_effect, effect_param, config)
    with option("--params"):
        rig = RigParams.from_file(params) if params else RigParams()
    return rig, comp, values


def effects_from_cli(
    add_effect: list[str] | None, effect_param: list[str] | None, config=None
) -> tuple[Composition, dict[str, float]]:
    """The composition and its effect values from the command-line options (errors name the option,
    the file, the effect and what is wrong); with ``config``, an effect that does not act in it is refused."""
    values = parse_effect_params(effect_param)
    if values and not add_effect:
        raise InputError(f"--effect-param {next(iter(values))}: no effect added (use --add-effect NAME)")
    comp, vals = compose_named(list(add_effect or []), values)
    if config is not None:
        check_effects_act(comp, config)
    return comp, vals
