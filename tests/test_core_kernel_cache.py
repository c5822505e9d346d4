"""Cached kernels are dropped when any drillgym source changes (numba keys a cache on one file only)."""

from drillgym._kernel_cache import invalidate_stale_kernels, sources_digest


def test_stale_kernels_are_dropped_when_a_source_changes(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "__pycache__").mkdir(parents=True)
    (pkg / "dynamics.py").write_text("A = 1\n")
    cached = pkg / "__pycache__" / "integrators.kernel-1.py311.nbi"
    assert invalidate_stale_kernels(pkg)  # first use: no stamp yet
    cached.write_text("compiled against A = 1")
    assert not invalidate_stale_kernels(pkg) and cached.exists()  # unchanged sources: cache kept
    before = sources_digest(pkg)
    (pkg / "dynamics.py").write_text("A = 2\n")
    assert sources_digest(pkg) != before
    assert invalidate_stale_kernels(pkg) and not cached.exists()  # edited dependency: cache dropped
