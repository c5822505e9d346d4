"""Kernel client templates of other packages: a composition's copy, named after the sources it imports.

:meth:`drillgym.effects.codegen.CompiledModel.client` specialises drillgym's own client templates, whose sources key
the composition's package.  A template of another package (a controller's law on the composition,
``controllers.compiled.composition_law``) is not among them, and numba keys a cached function on its own file only:
its copy is named after a SHA-256 of the sources of its package it imports at module level, transitively, and of the
drillgym modules those import, so an edit of any of them writes a new copy, compiled once and then loaded from
numba's cache.  (A module of its own, imported by no kernel source, so that adding it left every compiled package
valid.)
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import tempfile
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

from .._kernel_cache import PACKAGE_DIR, _imported_modules, _module_file, modules_digest

if TYPE_CHECKING:  # pragma: no cover
    from .codegen import CompiledModel

__all__ = ["foreign_client", "client_key"]

_LOADED: dict[tuple[str, str], ModuleType] = {}
#: each template's copy's name, its sources read once per process (as the modules themselves are)
_NAMES: dict[str, str] = {}


def client_key(module: str) -> str:
    """12 hex digits of a SHA-256 over the sources of ``module``'s package it imports at module level, transitively,
    and of the drillgym modules those import.

    Parameters
    ----------
    module : str
        The template, e.g. ``"controllers.compiled.composition_law"``.

    Returns
    -------
    str
        The key.
    """
    spec = importlib.util.find_spec(module.split(".")[0])
    if spec is None or spec.origin is None:
        raise ImportError(f"kernel client template {module} not found")
    pkg_dir = Path(spec.origin).resolve().parent
    seen: set[str] = set()
    todo, core = [module], set()
    while todo:
        mod = todo.pop()
        f = _module_file(mod, pkg_dir)
        if mod in seen or f is None:
            continue
        seen.add(mod)
        todo.extend(_imported_modules(f, pkg_dir))
        if f.is_relative_to(PACKAGE_DIR.parent):  # its drillgym imports (read as drillgym's own files read them)
            core |= _imported_modules(f, PACKAGE_DIR)
    own = modules_digest([module], package_dir=pkg_dir)
    return hashlib.sha256((own + modules_digest(sorted(core))).encode()).hexdigest()[:12]


def foreign_client(kernels: CompiledModel, module: str) -> ModuleType:
    """A composition's specialised copy of a client template of another package (module doc).

    Parameters
    ----------
    kernels : CompiledModel
        The composition's kernels (``composition.kernels``).
    module : str
        The template: a module importing ``drillgym.kernels.*``.

    Returns
    -------
    module
        The specialised module (written once into the composition's package).
    """
    from .codegen import _specialise, _template_source

    if module not in _NAMES:
        _NAMES[module] = "client_" + module.replace(".", "_") + "_" + client_key(module)
    name = _NAMES[module]
    key = (kernels.package, name)
    if key not in _LOADED:
        target = kernels.path / f"{name}.py"
        if not target.exists():
            fd, tmp = tempfile.mkstemp(prefix=f".{name}-", suffix=".py", dir=kernels.path)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(_specialise(_template_source(module), kernels.package))
            os.replace(tmp, target)
            importlib.invalidate_caches()
        _LOADED[key] = importlib.import_module(f"{kernels.package}.{name}")
    return _LOADED[key]
