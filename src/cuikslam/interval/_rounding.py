"""Directed rounding of single floating-point operations, for compiled kernels.

numba cannot switch the FPU rounding mode, so each result computed to nearest is moved
outward afterwards. Sums use an error-free transformation (TwoSum) and stay exact when
the float sum is exact (priors of width 0 stay width 0); products, quotients and square
roots, correctly rounded by IEEE 754, move outward by one or two ulps. Library transcendental
functions (sin, cos, tan, asin, acos, atan2) are within 1 ulp on the platforms we
support; we move them 2 ulp outward. ``tests/test_interval_rounding.py`` checks all of
this against mpmath.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam._jit import jit
from cuikslam.interval.angles import (  # noqa: F401 (the enclosures of pi, for the kernels)
    HALF_PI_HI,
    HALF_PI_LO,
    PI_HI,
    PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
)

MAX = np.finfo(np.float64).max
INF = np.inf


# One ulp of 1, and the smallest subnormal, written exactly (no arithmetic at import).
_ULP_OF_ONE = float.fromhex("0x1p-52")
_SMALLEST = float.fromhex("0x0.0000000000001p-1022")


@jit
def down(x: float) -> float:
    """A double below ``x``: its predecessor, or the one before (two multiplies and an add,
    much cheaper than ``nextafter``). |x| * 2**-52 is at least one ulp of x, so the
    difference rounds to a double strictly below x in any rounding mode."""
    if x == INF:
        return MAX
    return x - max(abs(x) * _ULP_OF_ONE, _SMALLEST)


@jit
def up(x: float) -> float:
    """A double above ``x``: its successor, or the one after (see :func:`down`)."""
    if x == -INF:
        return -MAX
    return x + max(abs(x) * _ULP_OF_ONE, _SMALLEST)


@jit
def _two_sum_error(a: float, b: float, s: float) -> float:
    bb = s - a
    return (a - (s - bb)) + (b - bb)


@jit
def add_down(a: float, b: float) -> float:
    """A lower bound of the exact ``a + b``."""
    s = a + b
    if math.isinf(s):
        if s > 0 and math.isfinite(a) and math.isfinite(b):
            return MAX
        return s
    # a NaN error (TwoSum's intermediate overflowed near MAX) is treated as inexact
    if not _two_sum_error(a, b, s) >= 0.0:
        return down(s)
    return s


@jit
def add_up(a: float, b: float) -> float:
    """An upper bound of the exact ``a + b``."""
    s = a + b
    if math.isinf(s):
        if s < 0 and math.isfinite(a) and math.isfinite(b):
            return -MAX
        return s
    if not _two_sum_error(a, b, s) <= 0.0:
        return up(s)
    return s


@jit
def sub_down(a: float, b: float) -> float:
    """A lower bound of the exact ``a - b``."""
    return add_down(a, -b)


@jit
def sub_up(a: float, b: float) -> float:
    """An upper bound of the exact ``a - b``."""
    return add_up(a, -b)


@jit
def mul_down(a: float, b: float) -> float:
    """A lower bound of the exact ``a * b``, with 0 * inf = 0 (interval convention)."""
    if a == 0.0 or b == 0.0:
        return 0.0
    return down(a * b)


@jit
def mul_up(a: float, b: float) -> float:
    """An upper bound of the exact ``a * b``, with 0 * inf = 0 (interval convention)."""
    if a == 0.0 or b == 0.0:
        return 0.0
    return up(a * b)


@jit
def div_down(a: float, b: float) -> float:
    """A lower bound of the exact ``a / b`` for ``b != 0``; 0 / b = 0.

    inf / inf (a corner of unbounded intervals) is the limit of quotients that take every
    value of its sign: 0 or -inf, never NaN (min and max would drop a NaN silently).
    """
    if a == 0.0:
        return 0.0
    if math.isinf(a) and math.isinf(b):
        return 0.0 if (a > 0.0) == (b > 0.0) else -INF
    return down(a / b)


@jit
def div_up(a: float, b: float) -> float:
    """An upper bound of the exact ``a / b`` for ``b != 0``; 0 / b = 0; inf / inf: inf or 0."""
    if a == 0.0:
        return 0.0
    if math.isinf(a) and math.isinf(b):
        return INF if (a > 0.0) == (b > 0.0) else 0.0
    return up(a / b)


@jit
def sqrt_down(a: float) -> float:
    """A lower bound of the exact square root of ``a >= 0``."""
    if a <= 0.0:
        return 0.0
    return max(0.0, down(math.sqrt(a)))


@jit
def sqrt_up(a: float) -> float:
    """An upper bound of the exact square root of ``a >= 0``."""
    if a <= 0.0:
        return 0.0
    return up(math.sqrt(a))


@jit
def libm_down(v: float) -> float:
    """A lower bound of a value that the C library returned within 1 ulp."""
    return down(down(v))


@jit
def libm_up(v: float) -> float:
    """An upper bound of a value that the C library returned within 1 ulp."""
    return up(up(v))
