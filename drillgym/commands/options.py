"""Errors in the options' terms: a refusal found deep in a reader names the option that gave the value.

>>> with option("--params"):
...     RigParams.from_file(path)      # "x.json: unknown parameter(s): who" -> "--params x.json: unknown ..."

And options that mean something only beside another, declared once where the command is defined and checked
before its body runs (so before anything is read or written): a one-line refusal instead of an option
silently ignored.

>>> @app.command("evaluate")
... @requires("--excitation", "--identify")
... @requires("--uncertainty", "--scenarios", when=lambda v: "plants" in v, what="--scenarios plants")
... @excludes("--model", "--identify", why="--identify builds the controllers on each plant's model")
... def evaluate_cmd(...): ...
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from ..errors import DrillgymError, InputError

__all__ = ["option", "named", "requires", "excludes", "Dependency", "dependencies_of", "check_dependencies"]


def named(name: str, exc: DrillgymError) -> DrillgymError:
    """``exc`` with its one-line message led by ``name`` (unchanged when it names it already).

    Parameters
    ----------
    name : str
        The option or argument, e.g. ``"--params"`` or ``"DATA"``.
    exc : DrillgymError
        The refusal.

    Returns
    -------
    DrillgymError
        An error of the same kind (or :class:`~drillgym.errors.InputError` if that kind cannot be
        rebuilt from a message) whose message starts with ``name``.
    """
    message = " ".join(str(exc).split())
    if name in message.split(":", 1)[0] or message.startswith(name):
        return exc
    text = f"{name} {message}" if message.startswith(("/", ".", "~")) else f"{name}: {message}"
    try:
        new = type(exc)(text)
    except Exception:  # a kind with its own constructor
        new = InputError(text)
    return new


@contextmanager
def option(name: str) -> Iterator[None]:
    """Within the block, a :class:`~drillgym.errors.DrillgymError` is re-raised naming ``name``.

    Parameters
    ----------
    name : str
        The option or argument whose value the block reads or checks.

    Raises
    ------
    DrillgymError
        The block's error, its message led by ``name``.
    """
    try:
        yield
    except DrillgymError as exc:
        new = named(name, exc)
        if new is exc:
            raise
        raise new from exc


# --------------------------------------------------------------------------------------- dependencies


@dataclass(frozen=True)
class Dependency:
    """``option`` given on the command line needs ``needs`` (``kind="requires"``) or refuses it (``"excludes"``).

    ``when``: a condition on the value of ``needs`` that satisfies it (default: given, i.e. a flag set, a value
    other than its default); ``what``: how the refusal names what is needed (default ``needs``, or ``needs`` and
    its ``alternatives`` joined by "or"); ``why``: a clause after the refusal; ``given``: a condition on the value
    of ``option`` under which the dependency holds (default: whenever it is given), with ``example``, a value of
    ``option`` that meets it; ``alternatives``: other options any of which satisfies a ``requires`` as well as
    ``needs`` (``--trust`` needs ``--model`` or ``--params``).
    """

    option: str
    needs: str
    kind: str = "requires"
    when: Callable[[Any], bool] | None = None
    what: str = ""
    why: str = ""
    given: Callable[[Any], bool] | None = None
    example: str = ""
    alternatives: tuple[str, ...] = ()

    @property
    def satisfiers(self) -> tuple[str, ...]:
        """The options any of which satisfies a ``requires``: ``needs``, then its alternatives."""
        return (self.needs, *self.alternatives)

    def message(self) -> str:
        """The one-line refusal: ``"--excitation needs --identify"``, ``"--teacher cannot go with --resume"``."""
        verb = "needs" if self.kind == "requires" else "cannot go with"
        text = f"{self.option} {verb} {self.what or ' or '.join(self.satisfiers)}"
        return f"{text} ({self.why})" if self.why else text


#: the attribute of a command function holding its declared dependencies
_ATTR = "__drillgym_dependencies__"


def dependencies_of(fn: Callable) -> tuple[Dependency, ...]:
    """The dependencies declared on the command function ``fn`` (or a wrapper of it: typer's, click's)."""
    while fn is not None:
        deps = getattr(fn, _ATTR, None)
        if deps is not None:
            return tuple(deps)
        fn = getattr(fn, "__wrapped__", None)
    return ()


def _option_names(name: str, default: Any) -> tuple[str, ...]:
    """The option strings of the parameter ``name`` (``--sparse``, ``--no-sparse``), from its typer default."""
    decls = [d for d in getattr(default, "param_decls", None) or () if isinstance(d, str)]
    names = [part for d in decls for part in d.split("/") if part.startswith("-")]
    return tuple(names) or ("--" + name.replace("_", "-"),)


def _default(info: Any) -> Any:
    default = getattr(info, "default", info)
    return None if default is ... else default


def _given(value: Any, default: Any) -> bool:
    """Whether a parameter was set: a value other than its default (an empty list is not set)."""
    if isinstance(value, (list, tuple)) and not value:
        return False
    return value is not None and value != default


def check_dependencies(fn: Callable, kwargs: dict[str, Any]) -> None:
    """Refuse, in one line, the first declared dependency of ``fn`` its arguments ``kwargs`` break.

    Parameters
    ----------
    fn : callable
        The command function (its signature's typer defaults name the options).
    kwargs : dict
        The parsed arguments, by parameter name.

    Raises
    ------
    InputError
        ``"--excitation needs --identify"`` and the like.
    """
    params = inspect.signature(fn).parameters
    by_option: dict[str, str] = {}
    for pname, par in params.items():
        for opt in _option_names(pname, par.default):
            by_option[opt] = pname
    for dep in dependencies_of(fn):
        a, bs = by_option.get(dep.option), [by_option.get(n) for n in dep.satisfiers]
        if a is None or None in bs:
            raise TypeError(f"{fn.__name__}: dependency {dep} names an option the command does not have")
        if not _given(kwargs.get(a), _default(params[a].default)):
            continue
        if dep.given is not None and not dep.given(kwargs.get(a)):
            continue
        has = False
        for name, b in zip(dep.satisfiers, bs):
            value = kwargs.get(b)
            if dep.when is not None:
                has = has or bool(dep.when(value))
            elif isinstance(value, bool):  # a flag: '--sparse' is given when on, '--no-sparse' when off
                has = has or value is not name.startswith("--no-")
            else:
                has = has or _given(value, _default(params[b].default))
        if has != (dep.kind == "requires"):
            raise InputError(dep.message())


def _declare(dep: Dependency) -> Callable[[Callable], Callable]:
    def decorate(fn: Callable) -> Callable:
        if hasattr(fn, _ATTR):  # already checked by a wrapper of ours: add the dependency to its table
            setattr(fn, _ATTR, (dep, *getattr(fn, _ATTR)))
            return fn

        @functools.wraps(fn)
        def checked(*args: Any, **kwargs: Any) -> Any:
            check_dependencies(checked, kwargs)  # its table: the dependencies declared on it
            return fn(*args, **kwargs)

        setattr(checked, _ATTR, (dep,))
        return checked

    return decorate


def requires(
    option: str,
    needs: str,
    *,
    when: Callable[[Any], bool] | None = None,
    what: str = "",
    why: str = "",
    given: Callable[[Any], bool] | None = None,
    example: str = "",
    alternatives: tuple[str, ...] = (),
) -> Callable[[Callable], Callable]:
    """Declare that ``option`` means something only beside ``needs``; decorate the command function with it
    (below ``@app.command``). Checked before the command's body runs: ``"--excitation needs --identify"``.

    Parameters
    ----------
    option : str
        The dependent option, e.g. ``"--excitation"``.
    needs : str
        The option it needs, e.g. ``"--identify"`` (a flag set, or any value other than its default).
    when : callable, optional
        A condition on the value of ``needs`` instead, e.g. ``lambda v: "plants" in v``.
    what : str, optional
        How the refusal names what is needed (default ``needs``), e.g. ``"--scenarios plants"``.
    why : str, optional
        A clause the refusal ends with, in parentheses.
    given : callable, optional
        The dependency holds only for values of ``option`` that meet this (e.g. ``--validate lower=FILE`` needs
        ``--lower``); ``example``: such a value.
    alternatives : tuple of str, optional
        Other options any of which satisfies it as well, e.g. ``("--params",)`` beside ``--model``: the
        refusal reads ``"--trust needs --model or --params"``.
    """
    return _declare(Dependency(option, needs, "requires", when, what, why, given, example, alternatives))


def excludes(
    option: str, other: str, *, when: Callable[[Any], bool] | None = None, what: str = "", why: str = ""
) -> Callable[[Callable], Callable]:
    """Declare that ``option`` cannot go with ``other`` (one of them would be ignored):
    ``"--teacher cannot go with --resume"``. Parameters as :func:`requires`."""
    return _declare(Dependency(option, other, "excludes", when, what, why))
