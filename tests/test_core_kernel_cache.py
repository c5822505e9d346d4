"""Cached kernels are dropped when a source they can see changes (numba keys a cache on one file only)."""

from drillgym._kernel_cache import invalidate_stale_kernels, sources_digest


def test_stale_kernels_are_dropped_when_a_source_changes(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "__pycache__").mkdir(parents=True)
    (pkg / "integrators.py").write_text("from .dynamics import A\n\n@njit(cache=True)\ndef kernel():\n    return A\n")
    (pkg / "dynamics.py").write_text("A = 1\n")
    (pkg / "cli.py").write_text("from .integrators import kernel\n")
    cached = pkg / "__pycache__" / "integrators.kernel-1.py311.nbi"
    assert invalidate_stale_kernels(pkg)  # first use: no stamp yet
    cached.write_text("compiled against A = 1")
    assert not invalidate_stale_kernels(pkg) and cached.exists()  # unchanged sources: cache kept
    before = sources_digest(pkg)
    (pkg / "cli.py").write_text("from .integrators import kernel  # no kernel imports the command line\n")
    assert sources_digest(pkg) == before and not invalidate_stale_kernels(pkg) and cached.exists()
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


def test_imports_no_kernel_can_see_do_not_key_the_generated_kernels(tmp_path):
    """A lazy import inside a function, or one under ``if TYPE_CHECKING:``, binds no global a kernel can
    reach: an edit of such a module (the diagnosis the package names for type checkers) keeps every model."""
    from drillgym._kernel_cache import modules_digest

    pkg = tmp_path / "drillgym"
    (pkg / "kernels").mkdir(parents=True)
    (pkg / "__init__.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import diagnosis\n"
    )
    (pkg / "kernels" / "__init__.py").write_text("")
    (pkg / "kernels" / "model.py").write_text(
        "from drillgym import friction\n"
        "try:\n    from drillgym import fast\nexcept ImportError:\n    fast = None\n"
        "def helper():\n    from drillgym import cli\n"
    )
    for name in ("friction", "fast", "cli", "diagnosis"):
        (pkg / f"{name}.py").write_text("X = 1\n")
    digest = lambda: modules_digest(["drillgym.kernels.model"], package_dir=pkg)  # noqa: E731
    before = digest()
    for name in ("cli", "diagnosis"):
        (pkg / f"{name}.py").write_text("X = 2\n")
        assert digest() == before, name
    for name in ("friction", "fast", "__init__"):  # module level, in a try block, the package imported from
        (pkg / f"{name}.py").write_text("X = 3\n")
        assert digest() != before, name
        before = digest()


def test_another_installations_packages_are_kept_while_it_loads_them(tmp_path):
    """The generated packages are shared by every drillgym that uses the cache: one built from other sources is
    removed only once no process has loaded it for STALE_AFTER_S (a long test run of another checkout keeps its
    packages), and loading a package marks it used."""
    import os
    import time

    from drillgym.effects import Composition
    from drillgym.effects.codegen import STALE_AFTER_S, USED_STAMP, _write_package, prune_stale

    old = time.time() - 2 * STALE_AFTER_S
    for name in ("_dgk_unused", "_dgk_loaded"):
        (tmp_path / name).mkdir()
        (tmp_path / name / USED_STAMP).write_text("another installation's sources\n")
        os.utime(tmp_path / name / USED_STAMP, (old, old))
        os.utime(tmp_path / name, (old, old))
    assert _write_package(tmp_path, "_dgk_loaded", "", Composition(())) == tmp_path / "_dgk_loaded"
    assert prune_stale(tmp_path) == 1
    assert not (tmp_path / "_dgk_unused").exists() and (tmp_path / "_dgk_loaded").exists()


def test_a_client_template_of_another_package_is_keyed_on_the_sources_it_imports(tmp_path, monkeypatch):
    import sys

    from drillgym.effects.foreign_client import client_key

    pkg = tmp_path / "lawpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text("from drillgym.params import IDX\nGAIN = 1.0\n")
    (pkg / "template.py").write_text("from lawpkg.helper import GAIN\nfrom drillgym.kernels.hooks import N_STATE\n")
    (pkg / "unrelated.py").write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("lawpkg", None)
    first = client_key("lawpkg.template")
    assert len(first) == 12
    (pkg / "unrelated.py").write_text("X = 2\n")  # a module the template does not import
    assert client_key("lawpkg.template") == first
    (pkg / "helper.py").write_text("from drillgym.params import IDX\nGAIN = 2.0\n")  # one it imports: a new copy
    assert client_key("lawpkg.template") != first


def test_the_controllers_model_functions_are_loaded_from_the_compositions_package():
    from controllers.dynamics import model_kernels
    from drillgym.effects import compose

    comp, _ = compose(["motor_lag"])
    kern = model_kernels(comp)
    assert kern.evaluate.py_func.__module__.startswith(comp.kernels.package + ".client_controllers_")
    assert kern.evaluate._cache.__class__.__name__ != "NullCache"  # cached on disk: compiled once, then loaded
