"""Keep numba's on-disk kernel cache consistent with drillgym's sources.

Numba's ``cache=True`` keys each compiled function on its *own* source file only.
drillgym's kernels inline functions from other modules (the friction laws and the
equations of motion into the integrators, the lane kernel, the environments), so
after an edit of, say, ``dynamics.py`` the cached ``integrators.py`` kernels would
still carry the old equations.  This module hashes every drillgym source file and
drops drillgym's cached kernels (``*.nbi``/``*.nbc``) whenever the hash changed
since they were written; they are recompiled on first use.
"""

from __future__ import annotations

import ast
import hashlib
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
STAMP_NAME = "kernel_sources.sha256"


def sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the relative paths and contents of the package's Python sources."""
    h = hashlib.sha256()
    for f in sorted(package_dir.rglob("*.py")):
        h.update(f.relative_to(package_dir).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()


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
    """drillgym modules a source file imports (anywhere in the file, relative imports resolved)."""
    rel = path.relative_to(package_dir.parent).with_suffix("")
    here = list(rel.parts[:-1])  # the package a relative import starts from (also for __init__)
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)  # ``from pkg import module``
    top = package_dir.name
    return {m for m in found if m == top or m.startswith(top + ".")}


def modules_digest(modules: list[str], extra_sources: tuple[str, ...] = (), package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the drillgym sources the given modules import, transitively (their parent
    packages' ``__init__`` included), plus ``extra_sources`` (source texts, e.g. generated code).

    The generated kernels are compiled from exactly these files, so an edit anywhere else (the CLI,
    diagnosis, controllers) leaves them valid."""
    seen: dict[str, Path] = {}
    todo = list(modules)
    while todo:
        mod = todo.pop()
        if mod in seen:
            continue
        parts = mod.split(".")
        for k in range(1, len(parts)):  # importing a.b.c runs a/__init__ and a/b/__init__
            todo.append(".".join(parts[:k]))
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
