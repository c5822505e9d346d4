"""Vectorisable elementary functions for the compiled kernels.

``vexp``, ``vlog``, ``vsincos`` and ``vpow`` are branch-free polynomial implementations
(Cody-Waite range reduction, Taylor/atanh series) without float<->int64
conversions, so that LLVM can vectorise a loop that calls them (calls to libm
would block vectorisation).  Accuracy: exp and log to a few 1e-16 relative,
sin/cos to about 4e-17 |x| absolute.  The scalar and the SIMD kernels both
use them, so that both compute the same numbers.

:data:`FASTMATH` are the floating-point flags every numba function of drillgym is compiled with: those that change
no finite value.  LLVM applies the others (a multiply and an add contracted into one rounding, sums reassociated,
a division turned into a multiplication by the reciprocal) wherever it sees the operations together, and it sees
more of them where it inlined a callee: a kernel compiled in a process that compiled its callees too, and one
compiled beside callees loaded from numba's cache, differed in the last bits, and an identification amplified that
into another model of the same recording.  Where a fused multiply-add pays, :func:`fma` asks for it explicitly:
one rounding, whatever was inlined.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["vexp", "vlog", "vsincos", "vpow", "fma", "FASTMATH"]

#: the fast-math flags of every numba function of drillgym: no NaN or infinity assumed, the sign of a zero free;
#: none that changes a finite value (module doc)
FASTMATH = {"nnan", "ninf", "nsz"}

_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LOG2E = 1.44269504088896338700e00


@intrinsic
def _f64_from_bits(typingctx, bits):
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


@intrinsic
def _bits_from_f64(typingctx, x):
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c rounded once (``llvm.fma``; one instruction on x86-64 with FMA, and it vectorises)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


_ROUND_MAGIC = 6755399441055744.0  # 1.5 * 2**52: x + magic rounds x to an integer held in the low bits
_ROUND_MAGIC_BITS = 0x4338000000000000
_EXP_MAGIC_BITS = 0x4330000000000000  # 2**52 as bits: OR-ing a small integer in gives 2**52 + integer


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def vexp(x: float) -> float:
    """exp(x) for -700 <= x <= 700 (clamped outside), relative error < 2e-15.

    Branch-free and free of float<->int64 conversions (which AVX2 lacks), so a loop of it vectorises.
    """
    x = min(max(x, -700.0), 700.0)
    nf = np.floor(x * _LOG2E + 0.5)
    r = (x - nf * _LN2_HI) - nf * _LN2_LO
    # Taylor series to r^13 on |r| <= ln2/2 (truncation < 1e-17)
    p = 1.0 / 6227020800.0
    p = fma(p, r, 1.0 / 479001600.0)
    p = fma(p, r, 1.0 / 39916800.0)
    p = fma(p, r, 1.0 / 3628800.0)
    p = fma(p, r, 1.0 / 362880.0)
    p = fma(p, r, 1.0 / 40320.0)
    p = fma(p, r, 1.0 / 5040.0)
    p = fma(p, r, 1.0 / 720.0)
    p = fma(p, r, 1.0 / 120.0)
    p = fma(p, r, 1.0 / 24.0)
    p = fma(p, r, 1.0 / 6.0)
    p = fma(p, r, 0.5)
    p = fma(p, r, 1.0)
    p = fma(p, r, 1.0)
    n = _bits_from_f64(nf + _ROUND_MAGIC) - _ROUND_MAGIC_BITS  # the integer nf, without cvttpd2qq
    return p * _f64_from_bits((n + 1023) << 52)


_PIO2_1 = 1.57079632673412561417e00  # pi/2 in three parts (Cody-Waite), exact products with k < 2**20
_PIO2_2 = 6.07710050650619224932e-11
_PIO2_3 = 2.02226624879595063154e-21
_TWO_OVER_PI = 6.36619772367581382433e-01


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def vsincos(x: float) -> tuple:
    """(sin x, cos x) for |x| < 1e5, absolute error about 4e-17 |x| (4e-15 at |x| = 100, 4e-14 at 1e3,
    measured against numpy); branch-free: the quadrant's swap and signs are float selects, so a loop of
    it vectorises."""
    kf = np.floor(x * _TWO_OVER_PI + 0.5)
    r = ((x - kf * _PIO2_1) - kf * _PIO2_2) - kf * _PIO2_3  # |r| <= pi/4
    r2 = r * r
    sp = -1.0 / 1307674368000.0
    sp = fma(sp, r2, 1.0 / 6227020800.0)
    sp = fma(sp, r2, -1.0 / 39916800.0)
    sp = fma(sp, r2, 1.0 / 362880.0)
    sp = fma(sp, r2, -1.0 / 5040.0)
    sp = fma(sp, r2, 1.0 / 120.0)
    sp = fma(sp, r2, -1.0 / 6.0)
    sin_r = r + r * r2 * sp
    cp = 1.0 / 20922789888000.0
    cp = fma(cp, r2, -1.0 / 87178291200.0)
    cp = fma(cp, r2, 1.0 / 479001600.0)
    cp = fma(cp, r2, -1.0 / 3628800.0)
    cp = fma(cp, r2, 1.0 / 40320.0)
    cp = fma(cp, r2, -1.0 / 720.0)
    cp = fma(cp, r2, 1.0 / 24.0)
    cp = fma(cp, r2, -0.5)
    cos_r = 1.0 + r2 * cp
    # quadrant q = kf mod 4 in floating point (no integer selects: nested ones block vectorisation);
    # odd quadrants swap sin and cos, the signs follow from q
    qf = kf - 4.0 * np.floor(kf * 0.25)
    half = np.floor(qf * 0.5)
    odd = qf - 2.0 * half > 0.5
    s_sign = 1.0 - 2.0 * half
    c_sign = 1.0 - 2.0 * np.floor((qf + 1.0 - 4.0 * np.floor((qf + 1.0) * 0.25)) * 0.5)
    a = cos_r if odd else sin_r
    b = sin_r if odd else cos_r
    sn = s_sign * a
    cs = c_sign * b
    return sn, cs


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def vlog(x: float) -> float:
    """Natural log for normal positive x, relative error < 3e-15; branch-free (vectorises)."""
    bits = _bits_from_f64(x)
    m = _f64_from_bits((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)  # mantissa in [1, 2)
    ef = _f64_from_bits(_EXP_MAGIC_BITS | ((bits >> 52) & 0x7FF)) - (4503599627370496.0 + 1023.0)
    big = m > 1.4142135623730951
    m = m * 0.5 if big else m
    ef = ef + 1.0 if big else ef
    s = (m - 1.0) / (m + 1.0)  # |s| <= 0.1716
    s2 = s * s
    q = 1.0 / 23.0
    q = fma(q, s2, 1.0 / 21.0)
    q = fma(q, s2, 1.0 / 19.0)
    q = fma(q, s2, 1.0 / 17.0)
    q = fma(q, s2, 1.0 / 15.0)
    q = fma(q, s2, 1.0 / 13.0)
    q = fma(q, s2, 1.0 / 11.0)
    q = fma(q, s2, 1.0 / 9.0)
    q = fma(q, s2, 1.0 / 7.0)
    q = fma(q, s2, 1.0 / 5.0)
    q = fma(q, s2, 1.0 / 3.0)
    q = fma(q, s2, 1.0)
    return 2.0 * s * q + ef * _LN2_HI + ef * _LN2_LO


_TINY = 1e-300


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def vpow(a: float, b: float) -> float:
    """a ** b as exp(b log |a|), relative error about 3e-16 (1 + |b ln a|); branch-free (vectorises).

    The power operator's special cases are float selects: 1 for b = 0, 0 for a = 0 and b > 0 (``+inf`` for
    b < 0), the sign of a negative base for an odd integral b, NaN for a negative base and a fractional b.
    Within |b ln |a|| <= 700 (``vexp``'s range; beyond it the result saturates near 1e304 or 1e-304 where
    ``**`` overflows or underflows).
    """
    m = abs(a)
    r = vexp(b * vlog(max(m, _TINY)))
    negative = a < 0.0
    odd = b - 2.0 * np.floor(b * 0.5) == 1.0  # an odd integer
    fractional = b != np.floor(b)
    r = -r if (negative & odd) else r  # & on the flags, not `and`: no branch, so the loop vectorises
    r = np.nan if (negative & fractional) else r
    at_zero = 0.0 if b > 0.0 else np.inf
    r = at_zero if m == 0.0 else r
    return 1.0 if b == 0.0 else r
