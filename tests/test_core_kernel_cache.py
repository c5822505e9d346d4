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


def test_full_vector_width_only_on_avx512_hosts(monkeypatch):
    from drillgym import _simd

    assert _simd.full_width_features("+avx2,+fma,-avx512f") is None
    f = _simd.full_width_features("+avx2,+avx512f,+prefer-256-bit")
    assert f.split(",")[-1] == "-prefer-256-bit" and "+prefer-256-bit" not in f.split(",")
    monkeypatch.setenv("DRILLGYM_SIMD", "256")  # the opt-out is honoured
    assert _simd.prefer_full_vector_width() is False
    monkeypatch.delenv("DRILLGYM_SIMD")
    monkeypatch.setenv("NUMBA_CPU_FEATURES", "+avx2")  # a user's own setting is never overridden
    assert _simd.prefer_full_vector_width() is False
    import os

    assert os.environ["NUMBA_CPU_FEATURES"] == "+avx2"


def test_generated_kernels_are_keyed_on_what_they_import_transitively(tmp_path):
    from drillgym._kernel_cache import modules_digest

    pkg = tmp_path / "drillgym"
    (pkg / "kernels").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "kernels" / "__init__.py").write_text("")
    (pkg / "kernels" / "model.py").write_text("from drillgym.dynamics import f\nfrom ..friction import g\n")
    (pkg / "dynamics.py").write_text("from . import vmath\n")
    (pkg / "friction.py").write_text("G = 1\n")
    (pkg / "vmath.py").write_text("V = 1\n")
    (pkg / "cli.py").write_text("C = 1\n")
    digest = lambda: modules_digest(["drillgym.kernels.model"], package_dir=pkg)  # noqa: E731
    before = digest()
    (pkg / "cli.py").write_text("C = 2\n")  # not imported by the kernels: same key
    assert digest() == before
    for name in ("vmath.py", "friction.py"):  # imported (transitively, relative import): new key
        (pkg / name).write_text("CHANGED = 1\n")
        assert digest() != before
        before = digest()
    assert modules_digest(["drillgym.kernels.model"], ("hooks A",), pkg) != modules_digest(
        ["drillgym.kernels.model"], ("hooks B",), pkg
    )
