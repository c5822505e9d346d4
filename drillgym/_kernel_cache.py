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


def invalidate_stale_kernels(package_dir: Path = PACKAGE_DIR) -> bool:
    """Delete the cached kernels when the sources changed; returns True when it did.
    A read-only installation is left alone (numba then caches elsewhere or compiles)."""
    stamp = package_dir / "__pycache__" / STAMP_NAME
    digest = sources_digest(package_dir)
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
