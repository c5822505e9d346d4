"""Names of a package imported on first use (PEP 562): ``import drillgym`` and ``--help`` stay light."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, lazy: Mapping[str, str], namespace: dict[str, Any]) -> tuple[Callable, Callable]:
    """A package's ``__getattr__`` and ``__dir__``: a name of ``lazy`` from its module, or a submodule.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    lazy : mapping of str to str
        Name -> the submodule (relative to ``package``) that defines it.
    namespace : dict
        The package's ``globals()``: a name, once imported, is kept there (the next look-up does not come back).

    Returns
    -------
    tuple of callable
        ``(__getattr__, __dir__)`` for the package's module.
    """

    def __getattr__(name: str) -> Any:
        module = lazy.get(name)
        if module is not None:
            value = getattr(importlib.import_module(f".{module}", package), name)
            namespace[name] = value
            return value
        if not name.startswith("__"):
            try:
                return importlib.import_module(f".{name}", package)
            except ModuleNotFoundError as exc:
                if exc.name != f"{package}.{name}":
                    raise
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(namespace.get("__all__", ())))

    return __getattr__, __dir__
