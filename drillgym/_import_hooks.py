"""Work drillgym does when another package is imported, not when drillgym is.

``import drillgym`` stays light: the command line imports the package to print its help or refuse
an option, and what used to run there loaded the LLVM library (110 MB) and the environments
(Gymnasium, numba, scipy: seconds). Two things are tied to the import of another package instead:

* :func:`drillgym._simd.prefer_full_vector_width` runs just *before* ``numba`` loads (it sets
  ``NUMBA_CPU_FEATURES``, which numba reads then), and so does
  :func:`drillgym._kernel_cache.invalidate_stale_kernels` (before any kernel is loaded from numba's cache;
  it hashes every source file, which the command line's help need not do);
* :func:`register_envs` runs just *after* ``gymnasium`` loads: the ids ``drillgym/Torsional-v0``, ...
  are registered by :mod:`drillgym.envs`, so ``import drillgym; import gymnasium;
  gymnasium.make("drillgym/Torsional-v0")`` works in either order. (Gymnasium >= 1.0 no longer loads
  the ``gymnasium.envs`` entry-point plugins older versions read, so this cannot be left to it.)

When the package is imported already, the work runs at once. The hook is a one-shot finder on
:data:`sys.meta_path` that finds nothing itself: it lets the other finders find the module and
wraps its loader's ``exec_module`` for that one import, then steps aside.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import warnings
from collections.abc import Callable
from importlib.abc import MetaPathFinder

__all__ = ["on_import", "before_numba", "register_envs", "install"]


def register_envs() -> None:
    """Import :mod:`drillgym.envs`, which registers the ids; an environment stack that cannot load
    (e.g. a broken numba) is reported as a warning instead of failing the caller's ``import gymnasium``."""
    try:
        importlib.import_module("drillgym.envs")
    except Exception as exc:  # the ids stay unregistered; gymnasium.make names the missing id
        warnings.warn(
            f"drillgym: the Gymnasium environments are not registered: {type(exc).__name__}: {exc}",
            RuntimeWarning,
            stacklevel=2,
        )


class _OnImport(MetaPathFinder):
    """Runs ``before`` and ``after`` around the execution of the top-level module ``name``."""

    def __init__(self, name: str, before: Callable[[], object] | None, after: Callable[[], object] | None):
        self.name, self.before, self.after = name, before, after

    def find_spec(self, fullname, path=None, target=None):
        if fullname != self.name:
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)  # the real finders (this hook is gone)
        loader = getattr(spec, "loader", None)
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        exec_module = loader.exec_module
        before, after = self.before, self.after

        def exec_module_around(module) -> None:
            try:
                del loader.exec_module  # back to the class's method
            except AttributeError:
                pass
            if before is not None:
                before()
            exec_module(module)
            if after is not None:
                after()

        loader.exec_module = exec_module_around
        return spec


def on_import(name: str, before: Callable[[], object] | None = None, after: Callable[[], object] | None = None):
    """Run ``before``/``after`` around the first import of the top-level module ``name``; if it is
    imported already, run them now (``before`` then too: the caller wants it done either way)."""
    if name in sys.modules:
        for work in (before, after):
            if work is not None:
                work()
        return
    sys.meta_path.insert(0, _OnImport(name, before, after))


def before_numba() -> None:
    """The SIMD width numba compiles for, and the kernel cache made consistent with the sources."""
    from ._kernel_cache import invalidate_stale_kernels
    from ._simd import prefer_full_vector_width

    prefer_full_vector_width()
    invalidate_stale_kernels()


def install() -> None:
    """The hooks of ``import drillgym``: :func:`before_numba`, and the Gymnasium ids after gymnasium."""
    if not any(isinstance(f, _OnImport) for f in sys.meta_path):
        on_import("numba", before=before_numba)
        on_import("gymnasium", after=register_envs)
