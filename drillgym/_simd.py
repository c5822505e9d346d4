"""Let LLVM use the host's full SIMD width for drillgym's kernels.

LLVM tunes Intel CPUs with AVX-512 to *prefer* 256-bit vectors (its ``prefer-256-bit``
tuning flag), so numba's loop vectoriser stays at AVX2 width there.  The batch lane
kernel (:mod:`drillgym.lanes`) is arithmetic-bound and runs about 20 % faster with 512-bit
vectors (``benchmarks/bench_simulator.py``).  :func:`prefer_full_vector_width` therefore
sets ``NUMBA_CPU_FEATURES`` to the host's own features plus ``-prefer-256-bit`` when

* the host has AVX-512 (``avx512f``),
* the user has set neither ``NUMBA_CPU_FEATURES`` nor ``NUMBA_CPU_NAME``, and
* ``DRILLGYM_SIMD`` is not ``256`` (the opt-out).

It only changes how wide LLVM's vectors are, not which instructions the host can run.
numba reads the setting when its CPU target is first used, so it applies to the whole
process when ``drillgym`` is imported before other numba code is compiled (otherwise it
has no effect): ``import drillgym`` applies it just before numba loads, or at once if numba
is loaded already (:mod:`drillgym._import_hooks`; reading the host's features loads LLVM,
which the command line's help need not do).  numba's cache keys kernels on the CPU
features, so the two widths never share a cached kernel.
"""

from __future__ import annotations

import os

OPT_OUT_VARIABLE = "DRILLGYM_SIMD"


def full_width_features(host_features: str) -> str | None:
    """The feature string that lifts the 256-bit preference, or None when the host has no AVX-512."""
    feats = host_features.split(",")
    if "+avx512f" not in feats:
        return None
    return ",".join([f for f in feats if f.lstrip("+-") != "prefer-256-bit"] + ["-prefer-256-bit"])


def prefer_full_vector_width() -> bool:
    """Apply the setting described in the module docstring; returns True when it was applied."""
    if os.environ.get(OPT_OUT_VARIABLE, "").strip() == "256":
        return False
    if os.environ.get("NUMBA_CPU_FEATURES") or os.environ.get("NUMBA_CPU_NAME"):
        return False
    try:
        import llvmlite.binding as ll

        ll.initialize_native_target()
        features = full_width_features(ll.get_host_cpu_features().flatten())
    except Exception:  # no native target information: leave numba's defaults
        return False
    if features is None:
        return False
    os.environ["NUMBA_CPU_FEATURES"] = features
    return True
