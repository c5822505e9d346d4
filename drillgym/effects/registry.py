"""Finding effects: by name (the library, installed packages), by file (``path/to/file.py:NAME``).

Installed packages provide effects through the entry-point group ``drillgym.effects``
(``name = "package.module:ClassName"``).  A user file is imported by path; ``NAME`` is the
effect's ``name`` or its class name.  Every failure is an :class:`EffectError` that names the
file, the effect and what is wrong.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import inspect
import os
import sys
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

from .base import Effect, EffectError
from .library import LIBRARY

__all__ = ["resolve_effect", "available_effects", "load_class_from_file", "effect_function", "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "drillgym.effects"
_FILE_MODULES: dict[str, Any] = {}


def effect_function(cls: type[Effect], name: str) -> Callable[..., Any]:
    """The plain function ``name`` of an effect class (a method written without self, or a staticmethod)."""
    f = inspect.getattr_static(cls, name)
    if isinstance(f, (staticmethod, classmethod)):
        f = f.__func__
    return f


def _import_file(path: Path) -> Any:
    """The module of an effect file, imported once per content: a file written again (an edited effect, a
    candidate file diagnose replaced) is imported again, not served from the first import."""
    if not path.is_file():
        raise EffectError(f"{path}: effect file not found")
    try:
        content = hashlib.sha256(path.read_bytes()).hexdigest()[:12]
    except OSError as exc:
        raise EffectError(f"{path}: effect file cannot be read ({exc.strerror or exc})") from None
    key = f"{path}:{content}"
    if key in _FILE_MODULES:
        return _FILE_MODULES[key]
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    modname = f"drillgym_user_effects.{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(modname, path)
    if spec is None or spec.loader is None:
        raise EffectError(f"{path}: cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[modname] = module
    try:
        with _no_process_exit():
            spec.loader.exec_module(module)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any import failure (sys.exit too) in one line
        sys.modules.pop(modname, None)
        where = ""
        tb = exc.__traceback__
        while tb is not None:
            if tb.tb_frame.f_code.co_filename == str(path):
                where = f" (line {tb.tb_lineno})"
            tb = tb.tb_next
        if isinstance(exc, _ProcessExit):
            raise EffectError(f"{path}: effect file calls os._exit({exc.code!r}) when imported{where}") from None
        if isinstance(exc, SystemExit):
            raise EffectError(f"{path}: effect file calls sys.exit({exc.code!r}) when imported{where}") from None
        raise EffectError(f"{path}: effect file does not import{where}: {type(exc).__name__}: {exc}") from None
    _FILE_MODULES[key] = module
    return module


class _ProcessExit(Exception):
    """``os._exit`` called while an effect file is imported (it would end drillgym with no word)."""

    def __init__(self, code: Any) -> None:
        super().__init__(code)
        self.code = code


@contextlib.contextmanager
def _no_process_exit():
    """``os._exit`` raises :class:`_ProcessExit` instead of ending the process, while an effect file imports."""
    real = os._exit

    def refuse(code: Any = 0) -> None:
        raise _ProcessExit(code)

    os._exit = refuse
    try:
        yield
    finally:
        os._exit = real


def _effects_in(module: Any) -> list[type[Effect]]:
    return [
        v
        for v in vars(module).values()
        if inspect.isclass(v) and issubclass(v, Effect) and v.__module__ == module.__name__ and v.kind
    ]


def _defined(module: Any) -> str:
    """The names of the effects a file's module defines, for a message ("none" when it defines none)."""
    return ", ".join(c.name or c.__name__ for c in _effects_in(module)) or "none"


def load_class_from_file(path: str | Path, name: str) -> type[Effect]:
    """The effect class defined in a Python file.

    Parameters
    ----------
    path : str or path
        The Python file (imported once per process).
    name : str
        The effect's ``name`` or its class name.

    Returns
    -------
    type
        The Effect subclass.

    Raises
    ------
    EffectError
        The file does not exist or does not import (the message gives the line), or defines no such effect.
    """
    path = Path(path).expanduser().resolve()
    module = _import_file(path)
    found = [c for c in _effects_in(module) if name in (c.name, c.__name__, c.__qualname__)]
    named = [c for c in _effects_in(module) if c.name == name]
    if len(named) > 1:
        classes = ", ".join(c.__qualname__ for c in named)
        raise EffectError(f"{path}: {len(named)} effects are named {name!r} ({classes}): give each its own name")
    if not found:
        obj = getattr(module, name, None)
        if isinstance(obj, Effect):
            found = [type(obj)]
    if not found:
        raise EffectError(f"{path}: no effect named {name!r} in the file (it defines: {_defined(module)})")
    cls = found[0]
    cls.__drillgym_file__ = str(path)
    return cls


def _entry_points() -> dict[str, metadata.EntryPoint]:
    try:
        eps = metadata.entry_points(group=ENTRY_POINT_GROUP)
    except TypeError:  # pragma: no cover - Python < 3.10
        eps = metadata.entry_points().get(ENTRY_POINT_GROUP, [])
    return {ep.name: ep for ep in eps}


def available_effects() -> dict[str, type[Effect]]:
    """Every effect known by name: the library, then installed packages' entry points.

    Returns
    -------
    dict of str to Effect subclass
        Effect classes by name; a library name wins over an entry point of the same name.
    """
    out: dict[str, type[Effect]] = dict(LIBRARY)
    for name, ep in _entry_points().items():
        if name in out:
            continue
        try:
            obj = ep.load()
        except Exception as exc:  # noqa: BLE001
            raise EffectError(
                f"entry point {ENTRY_POINT_GROUP}:{name} ({ep.value}) does not load: {type(exc).__name__}: {exc}"
            ) from None
        cls = type(obj) if isinstance(obj, Effect) else obj
        if not (inspect.isclass(cls) and issubclass(cls, Effect)):
            raise EffectError(f"entry point {ENTRY_POINT_GROUP}:{name} ({ep.value}) is not a drillgym Effect class")
        out[name] = cls
    return out


def resolve_effect(spec: str | type[Effect] | Effect) -> type[Effect] | Effect:
    """An effect class (or instance, passed through) from a spec.

    Parameters
    ----------
    spec : str, Effect subclass or Effect
        An Effect class or instance, a name (library or entry point), or ``path/to/file.py:NAME``.

    Returns
    -------
    Effect subclass or Effect
        The class, or the instance given.

    Raises
    ------
    EffectError
        An unknown name, a file spec without ``:NAME``, or anything else.
    """
    if isinstance(spec, Effect) or (inspect.isclass(spec) and issubclass(spec, Effect)):
        return spec
    if not isinstance(spec, str) or not spec.strip():
        raise EffectError(f"effect {spec!r}: expected a name, 'path/to/file.py:NAME' or an Effect class")
    spec = spec.strip()
    if ".py:" in spec or spec.endswith(".py"):
        path, _, name = spec.rpartition(":") if ".py:" in spec else (spec, "", "")
        if not name:
            module = _import_file(Path(path).expanduser().resolve())  # a missing or broken file says so first
            raise EffectError(
                f"{spec}: say which effect of the file to use: {spec}:NAME (it defines: {_defined(module)})"
            )
        return load_class_from_file(path, name)
    known = LIBRARY if spec in LIBRARY else available_effects()
    if spec not in known:
        raise EffectError(
            f"unknown effect {spec!r}; known effects: {', '.join(sorted(known))} (or give a file: path/to/file.py:NAME)"
        )
    return known[spec]
