"""Branch-free float64 exp, expm1, tanh, elu, log and power for the compiled march
(model/fast_march.py), inlined into its loops.

libm's tanh, exp and pow are opaque calls that block LLVM's vectoriser (tanh alone cost ~30 ns
an aircraft-step); these are plain arithmetic on the IEEE-754 bits, so the loops over aircraft
become SIMD code.  They agree with libm to a few ulp (tests/model/test_fast_march_math.py).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from llvmlite import ir as llvm_ir
from numba import njit
from numba import types as numba_types
from numba.extending import intrinsic


def _float_bits_typing(typingctx, x):
    """The IEEE-754 bits of a float64 as an int64 (a bit cast, no conversion)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvm_ir.IntType(64))

    return numba_types.int64(numba_types.float64), codegen


def _bits_float_typing(typingctx, x):
    """The float64 whose IEEE-754 bits are the int64 x."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], llvm_ir.DoubleType())

    return numba_types.float64(numba_types.int64), codegen


# Any: mypy reads an intrinsic's typing signature (typingctx, x) as its call signature.
_float_bits: Any = intrinsic(_float_bits_typing)
_bits_float: Any = intrinsic(_bits_float_typing)


_LOG2_E = 1.4426950408889634
_LN2_HI, _LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10  # Cody-Waite split
_EXP_OVERFLOW = 709.782712893384  # log(largest float64)


@njit(inline="always", error_model="numpy")
def _exp_parts(x):
    """(s, q) with exp(x) = s * (1 + q), s = 2**k, |q| < 0.42; x is clamped to [-600, 709].

    Keeping q apart gives expm1 without cancellation near 0.  Taylor series to r**13 on
    |r| <= ln(2) / 2: truncation below 1e-16 relative; measured within 3 ulp of libm.  The low
    clamp keeps s * q clear of subnormal floats (each costs a ~100-cycle microcode assist; hit
    by every dK <= 0 step); callers only need exp(x) ~ 0 there (tanh, elu, da of ~1e-260 m).
    """
    x = min(max(x, -600.0), 709.0)
    k = math.floor(x * _LOG2_E + 0.5)
    r = (x - k * _LN2_HI) - k * _LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    scale = _bits_float((np.int64(k) + 1023) << 52)
    return scale, r + r * r * p


@njit(inline="always", error_model="numpy")
def expm1(x):
    scale, q = _exp_parts(x)
    return (scale - 1.0) + scale * q


@njit(inline="always", error_model="numpy")
def tanh(x):
    t = expm1(-2.0 * abs(x))  # tanh|x| = -t / (2 + t), no cancellation for small |x|
    return math.copysign(-t / (2.0 + t), x)


@njit(inline="always", error_model="numpy")
def elu(x):
    return x if x > 0.0 else expm1(min(x, 0.0))


_SQRT_2 = 1.4142135623730951


@njit(inline="always", error_model="numpy")
def log(x):
    """Natural log of a positive normal float: exponent from the bits, then 2 atanh((u-1)/(u+1))
    for the mantissa u in [sqrt(1/2), sqrt(2)) (series to f**23: truncation below 1e-18)."""
    bits = _float_bits(x)
    exponent = (bits >> 52) - 1023
    mantissa = _bits_float((bits & 0x000FFFFFFFFFFFFF) | 0x3FF0000000000000)
    high = mantissa > _SQRT_2
    mantissa = mantissa * 0.5 if high else mantissa
    e = float(exponent + 1 if high else exponent)
    f = (mantissa - 1.0) / (mantissa + 1.0)
    f2 = f * f
    p = 1.0 / 23.0
    p = p * f2 + 1.0 / 21.0
    p = p * f2 + 1.0 / 19.0
    p = p * f2 + 1.0 / 17.0
    p = p * f2 + 1.0 / 15.0
    p = p * f2 + 1.0 / 13.0
    p = p * f2 + 1.0 / 11.0
    p = p * f2 + 1.0 / 9.0
    p = p * f2 + 1.0 / 7.0
    p = p * f2 + 1.0 / 5.0
    p = p * f2 + 1.0 / 3.0
    return e * _LN2_HI + (2.0 * f + (2.0 * f * f2 * p + e * _LN2_LO))


@njit(inline="always", error_model="numpy")
def power(x, m):
    """x**m for a positive finite x (relative error ~1e-15 for x**m within 1e+-100)."""
    return power_of_log(log(x), m)


@njit(inline="always", error_model="numpy")
def power_of_log(log_x, m):
    """x**m from log(x): `power`, for callers raising one x to several exponents."""
    y = m * log_x
    scale, q = _exp_parts(y)
    return math.inf if y > _EXP_OVERFLOW else scale + scale * q


@njit(inline="always", error_model="numpy")
def paris_growth(dk, c, m):
    """C * max(dK, 0)**m, with torch's results for dK = 0, +-inf and nan."""
    return paris_growth_of_log(dk, log(max(dk, 1e-300)), c, m)


@njit(inline="always", error_model="numpy")
def paris_growth_of_log(dk, log_dk, c, m):
    """paris_growth with log(max(dK, 1e-300)) given."""
    growth = c * power_of_log(log_dk, m)
    growth = growth if dk > 0.0 else 0.0
    return growth if abs(dk) < math.inf else (0.0 if dk < 0.0 else c * dk)
