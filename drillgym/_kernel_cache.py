"""Keep numba's on-disk kernel cache consistent with drillgym's sources.

Numba's ``cache=True`` keys each compiled function on its *own* source file only.
drillgym's kernels inline functions from other modules (the friction laws and the
equations of motion into the integrators, the lane kernel, the environments), so
after an edit of, say, ``dynamics.py`` the cached ``integrators.py`` kernels would
still carry the old equations.  This module hashes the sources the kernels can see
(the modules that cache kernels and what they import at module level) and drops
drillgym's cached kernels (``*.nbi``/``*.nbc``) whenever the hash changed since they
were written; they are recompiled on first use.
"""

from __future__ import annotations

import ast
import hashlib
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
STAMP_NAME = "kernel_sources.sha256"


def sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the sources numba's on-disk cache of the package depends on.

    The modules that cache kernels (their source says ``cache=True``) and the drillgym modules they import at
    module level, transitively (:func:`modules_digest`): an edit of a module no kernel can see (the diagnosis,
    the command line) keeps the compiled kernels."""
    top = package_dir.name
    roots = []
    for f in sorted(package_dir.rglob("*.py")):
        if "cache=True" in f.read_text(encoding="utf-8"):
            parts = f.relative_to(package_dir).with_suffix("").parts
            parts = parts[:-1] if parts[-1] == "__init__" else parts
            roots.append(".".join((top, *parts)))
    return modules_digest(roots, package_dir=package_dir)


def _module_file(module: str, package_dir: Path) -> Path | None:
    parts = module.split(".")
    if parts[0] != package_dir.name:
        return None
    base = package_dir.joinpath(*parts[1:])
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imported_modules(path: Path, package_dir: Path) -> set[str]:
    """drillgym modules a source file imports at module level (relative imports resolved).

    Only these can reach compiled code: numba resolves a kernel's globals, and a module's globals come from its
    module-level imports.  An import inside a function (a lazy import of plain Python code) or under ``if
    TYPE_CHECKING:`` (annotations) binds no global a kernel can see, so it does not key the kernels: the package's
    ``__init__`` names the diagnosis for type checkers, and an edit there must not recompile every model."""
    rel = path.relative_to(package_dir.parent).with_suffix("")
    here = list(rel.parts[:-1])  # the package a relative import starts from (also for __init__)
    found: set[str] = set()

    def visit(statements: list[ast.stmt]) -> None:
        for node in statements:
            if isinstance(node, ast.If):
                test = node.test
                name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
                if name != "TYPE_CHECKING":
                    visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)
                for handler in node.handlers:
                    visit(handler.body)
                visit(node.orelse)
                visit(node.finalbody)
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[: len(here) - node.level + 1]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                found.add(mod)
                found.update(f"{mod}.{a.name}" for a in node.names)  # ``from pkg import module``

    visit(ast.parse(path.read_text(encoding="utf-8")).body)
    top = package_dir.name
    return {m for m in found if m == top or m.startswith(top + ".")}


def modules_digest(modules: list[str], extra_sources: tuple[str, ...] = (), package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the drillgym sources the given modules import at module level, transitively, plus
    ``extra_sources`` (source texts, e.g. generated code).

    The generated kernels are compiled from exactly these files, so an edit anywhere else (the CLI,
    diagnosis, controllers, a package's ``__init__`` that only imports them) leaves them valid."""
    seen: dict[str, Path] = {}
    todo = list(modules)
    while todo:
        mod = todo.pop()
        if mod in seen:
            continue
        f = _module_file(mod, package_dir)
        if f is None:
            continue
        seen[mod] = f
        todo.extend(_imported_modules(f, package_dir) - seen.keys())
    h = hashlib.sha256()
    for f in sorted(set(seen.values())):
        h.update(f.relative_to(package_dir).as_posix().encode())
        h.update(f.read_bytes())
    for text in extra_sources:
        h.update(text.encode())
    return h.hexdigest()


def invalidate_stale_kernels(
    package_dir: Path = PACKAGE_DIR, digest: str | None = None, stamp_name: str = STAMP_NAME
) -> bool:
    """Delete the cached kernels under ``package_dir`` when the sources changed; returns True when it did.

    ``digest`` names the sources (default :func:`sources_digest` of ``package_dir``), kept in
    ``__pycache__/stamp_name``.  A read-only installation is left alone (numba then caches elsewhere or
    compiles)."""
    stamp = package_dir / "__pycache__" / stamp_name
    digest = sources_digest(package_dir) if digest is None else digest
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    try:
        for f in list(package_dir.rglob("*.nbi")) + list(package_dir.rglob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest)
    except OSError:
        return False
    return True
