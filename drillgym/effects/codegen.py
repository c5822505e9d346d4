"""Code generation: one compiled model per composition of effects, cached on disk by content.

For a composition (an ordered tuple of effect classes) :func:`build_kernels` writes its hooks
(:func:`drillgym.effects.hookgen.hooks_source`), then a specialised copy of each kernel template
(:data:`CORE_TEMPLATES` of :mod:`drillgym.kernels`, and client templates such as the
environments' period kernel, :meth:`CompiledModel.client`) that imports the generated hooks.
numba compiles them on first use and caches the machine code next to the generated files
(``cache=True``).

The files live in ``$DRILLGYM_KERNEL_CACHE`` (default ``~/.cache/drillgym/kernels``) in a
package named after a SHA-256 of everything the code depends on: the generated hooks, every
drillgym source file the templates and the code generator import, the effects' own source files,
numba's and Python's versions. A changed effect file or drillgym source gives a new package, so a
cached composition is never stale.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import shutil
import sys
import tempfile
import time
from functools import lru_cache
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numba

from .._kernel_cache import modules_digest
from .file_signature import code_signature
from .hookgen import effect_file_copy, hooks_source

if TYPE_CHECKING:  # pragma: no cover
    from .composition import Composition

__all__ = [
    "cache_root",
    "hooks_source",
    "build_kernels",
    "CompiledModel",
    "CORE_TEMPLATES",
    "CLIENT_TEMPLATES",
    "package_name",
    "prune_stale",
    "STALE_AFTER_S",
    "USED_STAMP",
]

#: the kernel templates of :mod:`drillgym.kernels` copied into every generated package
CORE_TEMPLATES = ("model", "commands", "stepping", "adaptive", "lane_steps", "lanes")
#: client templates (modules whose compiled code calls the kernels; see :meth:`CompiledModel.client`). The
#: generated packages are keyed on the sources these and the core templates import, transitively.
CLIENT_TEMPLATES = (
    "drillgym.envs.period_kernel",
    "drillgym.envs.sensor_kernel",
    "drillgym.bifurcation.flows",
    "drillgym.closed_loop.kernel",
)
_TEMPLATE_PACKAGE = "drillgym.kernels"


def cache_root() -> Path:
    """Directory of the generated kernel packages.

    Returns
    -------
    pathlib.Path
        ``$DRILLGYM_KERNEL_CACHE`` if set, else ``$XDG_CACHE_HOME/drillgym/kernels`` (default
        ``~/.cache/drillgym/kernels``).
    """
    env = os.environ.get("DRILLGYM_KERNEL_CACHE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "drillgym" / "kernels"


@lru_cache(maxsize=1)
def _environment_digest() -> str:
    h = hashlib.sha256()
    roots = [f"{_TEMPLATE_PACKAGE}.{name}" for name in (*CORE_TEMPLATES, "hooks")] + list(CLIENT_TEMPLATES)
    # the generated hooks import these (see hooks_source), and the code generator writes the hooks
    roots += [
        "drillgym.effects.registry",
        "drillgym.effects.simd",
        "drillgym.effects.library",
        "drillgym.effects.codegen",
        "drillgym.effects.hookgen",
        "drillgym.effects.hook_context",
        "drillgym.vmath",
    ]
    h.update(modules_digest(roots).encode())
    h.update(numba.__version__.encode())
    h.update(sys.version.encode())
    return h.hexdigest()


def _template_source(module: str) -> str:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ImportError(f"kernel template {module} not found")
    return Path(spec.origin).read_text(encoding="utf-8")


def _specialise(source: str, package: str) -> str:
    """A template's source importing the composition's package instead of drillgym.kernels."""
    return source.replace(f"from {_TEMPLATE_PACKAGE}.", f"from {package}.")


def package_name(comp: Composition, hooks: str) -> str:
    """The name of a composition's generated package: a digest of everything its code depends on.

    Parameters
    ----------
    comp : Composition
        The composition of effects.
    hooks : str
        Its generated hooks source (:func:`hooks_source`).

    Returns
    -------
    str
        ``"_dgk_"`` followed by 24 hex digits of a SHA-256 over the drillgym sources the templates
        and the code generator import, numba's and Python's versions, the hooks, the code of the
        effect files (:func:`~drillgym.effects.file_signature.code_signature`: not where they are,
        nor their parameters' guesses and words) and other effect modules' sources.
    """
    h = hashlib.sha256()
    h.update(_environment_digest().encode())
    h.update(hooks.encode())
    for eff in comp.effects:
        origin = getattr(eff, "__drillgym_file__", None)
        if origin:
            h.update(code_signature(Path(origin).read_text(encoding="utf-8")).encode())
            continue
        if not eff.__module__.startswith("drillgym."):  # e.g. an entry-point effect
            origin = getattr(sys.modules.get(eff.__module__), "__file__", None)
        if origin:
            h.update(Path(origin).read_bytes())
    return "_dgk_" + h.hexdigest()[:24]


def _ensure_on_path(root: Path) -> None:
    s = str(root)
    if s not in sys.path:
        sys.path.insert(0, s)


#: packages built from other drillgym sources are removed after a day in which no process loaded them
STALE_AFTER_S = 86400.0
#: the file of a generated package whose modification time is its last use (:func:`_write_package` touches it)
USED_STAMP = "ENVIRONMENT"


def prune_stale(root: Path) -> int:
    """Remove generated packages built from other drillgym sources, not loaded for :data:`STALE_AFTER_S`.

    This drillgym never loads them again (the package name hashes the sources), but another installation
    sharing the cache may be using them: every load marks a package used (:data:`USED_STAMP`), so a test run or a
    training of another checkout keeps its packages while it runs.

    Parameters
    ----------
    root : pathlib.Path
        The directory of the generated packages (:func:`cache_root`).

    Returns
    -------
    int
        How many packages were removed.
    """
    digest = _environment_digest()
    removed = 0
    now = time.time()
    for d in root.glob("_dgk_*"):
        try:
            stamp = d / USED_STAMP
            meta = stamp.read_text().strip()
            if meta != digest and now - stamp.stat().st_mtime > STALE_AFTER_S:
                shutil.rmtree(d, ignore_errors=True)
                removed += 1
        except OSError:
            continue
    return removed


def _write_package(root: Path, package: str, hooks: str, comp: Composition) -> Path:
    final = root / package
    if final.exists():
        try:
            os.utime(final / USED_STAMP)  # in use: another installation's prune keeps it
        except OSError:  # a read-only cache, or one being written by another process
            pass
        return final
    root.mkdir(parents=True, exist_ok=True)
    prune_stale(root)
    tmp = Path(tempfile.mkdtemp(prefix=f".{package}-", dir=root))
    try:
        (tmp / "ENVIRONMENT").write_text(_environment_digest() + "\n")
        (tmp / "__init__.py").write_text(f'"""drillgym kernels for the composition {comp.label!r} (generated)."""\n')
        (tmp / "hooks.py").write_text(hooks)
        for i, eff in enumerate(comp.effects):  # the effect files the hooks load (hookgen.effect_file_copy)
            origin = getattr(eff, "__drillgym_file__", None)
            if origin:
                shutil.copyfile(origin, tmp / effect_file_copy(i))
        for name in CORE_TEMPLATES:
            (tmp / f"{name}.py").write_text(_specialise(_template_source(f"{_TEMPLATE_PACKAGE}.{name}"), package))
        try:
            os.rename(tmp, final)
        except OSError:  # another process wrote it first
            shutil.rmtree(tmp, ignore_errors=True)
    finally:
        if tmp.exists() and final.exists() and tmp != final:
            shutil.rmtree(tmp, ignore_errors=True)
    return final


def build_kernels(comp: Composition) -> CompiledModel:
    """The specialised kernel modules of a composition, written once, then loaded from the cache.

    Parameters
    ----------
    comp : Composition
        The composition of effects.

    Returns
    -------
    CompiledModel
        Its kernel modules (compiled by numba on first use).

    Raises
    ------
    EffectError
        A function of a user's effect that numba cannot compile (checked once, before the composition's
        package is written: :func:`drillgym.effects.compile_check.check_compiles`).
    """
    hooks = hooks_source(comp)
    package = package_name(comp, hooks)
    root = cache_root()
    if not (root / package).exists():  # a new composition: its user effects' bodies compiled alone first
        from .compile_check import check_compiles

        check_compiles(comp)
    _write_package(root, package, hooks, comp)
    _ensure_on_path(root)
    importlib.invalidate_caches()
    return CompiledModel(package, root)


def _load_compiled_model(package: str, root: str, clients: tuple = ()) -> CompiledModel:
    _ensure_on_path(Path(root))
    model = CompiledModel(package, Path(root))
    for c in clients:
        model.client(c)
    return model


class CompiledModel:
    """The kernels of one composition, loaded from its generated package.

    Parameters
    ----------
    package : str
        The generated package's name (:func:`package_name`).
    root : pathlib.Path
        The directory holding it (:func:`cache_root`).

    Attributes
    ----------
    hooks, model, stepping, adaptive, lanes : module
        The generated hooks and the specialised kernel templates; :meth:`client` gives specialised
        client templates.
    """

    def __init__(self, package: str, root: Path) -> None:
        self.package = package
        self.root = root
        self.hooks = importlib.import_module(f"{package}.hooks")
        self.model = importlib.import_module(f"{package}.model")
        self.stepping = importlib.import_module(f"{package}.stepping")
        self.adaptive = importlib.import_module(f"{package}.adaptive")
        self.lanes = importlib.import_module(f"{package}.lanes")
        self._clients: dict[str, ModuleType] = {}

    @property
    def path(self) -> Path:
        return self.root / self.package

    def __reduce__(self):  # modules do not pickle: rebuild from the package (written on disk)
        return (_load_compiled_model, (self.package, str(self.root), tuple(self._clients)))

    def client(self, module: str) -> ModuleType:
        """A specialised copy of a client template, its ``drillgym.kernels.*`` imports pointing here.

        Parameters
        ----------
        module : str
            A drillgym module whose compiled code calls the kernels, e.g.
            ``"drillgym.bifurcation.flows"`` (see :data:`CLIENT_TEMPLATES`).

        Returns
        -------
        module
            The specialised module (written once into this composition's package).
        """
        if module not in self._clients:
            name = "client_" + module.replace(".", "_")
            target = self.path / f"{name}.py"
            if not target.exists():
                text = _specialise(_template_source(module), self.package)
                fd, tmp = tempfile.mkstemp(prefix=f".{name}-", suffix=".py", dir=self.path)
                with os.fdopen(fd, "w", encoding="utf-8") as f:
                    f.write(text)
                os.replace(tmp, target)
                importlib.invalidate_caches()
            self._clients[module] = importlib.import_module(f"{self.package}.{name}")
        return self._clients[module]
