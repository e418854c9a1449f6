"""Compiled interval arithmetic on ``(lo, hi)`` pairs: forward operations and backward projections.

An interval is a pair of floats; it is empty when ``lo > hi`` (the canonical empty
interval is ``(inf, -inf)``). Every forward operation returns an enclosure of the exact
range; every backward projection (HC4-revise) narrows its arguments to those values that
can produce a value in the result's interval, and never removes such a value.
"""

from __future__ import annotations

import math

from cuikslam._jit import jit
from cuikslam.interval._rounding import (
    INF,
    add_down,
    add_up,
    div_down,
    div_up,
    mul_down,
    mul_up,
    sqrt_down,
    sqrt_up,
    sub_down,
    sub_up,
)

EMPTY = (INF, -INF)


@jit
def is_empty(lo: float, hi: float) -> bool:
    """True for an empty interval (``lo > hi``); NaN is *not* empty: it must prove nothing."""
    return lo > hi


@jit
def meet(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Intersection of two intervals."""
    lo = max(alo, blo)
    hi = min(ahi, bhi)
    if lo > hi:
        return EMPTY
    return lo, hi


@jit
def join(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Hull (smallest interval containing both)."""
    if alo > ahi:
        return blo, bhi
    if blo > bhi:
        return alo, ahi
    return min(alo, blo), max(ahi, bhi)


@jit
def neg(alo: float, ahi: float) -> tuple[float, float]:
    if alo > ahi:
        return EMPTY
    return -ahi, -alo


@jit
def add(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    if alo > ahi or blo > bhi:
        return EMPTY
    return add_down(alo, blo), add_up(ahi, bhi)


@jit
def sub(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    if alo > ahi or blo > bhi:
        return EMPTY
    return sub_down(alo, bhi), sub_up(ahi, blo)


@jit
def mul(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    if alo > ahi or blo > bhi:
        return EMPTY
    lo = min(
        min(mul_down(alo, blo), mul_down(alo, bhi)),
        min(mul_down(ahi, blo), mul_down(ahi, bhi)),
    )
    hi = max(
        max(mul_up(alo, blo), mul_up(alo, bhi)),
        max(mul_up(ahi, blo), mul_up(ahi, bhi)),
    )
    return lo, hi


@jit
def div(alo: float, ahi: float, blo: float, bhi: float) -> tuple[float, float]:
    """Hull of ``{a / b : a in A, b in B, b != 0}`` (relational division, for backward ``mul``)."""
    if alo > ahi or blo > bhi:
        return EMPTY
    if blo > 0.0 or bhi < 0.0:
        lo = min(
            min(div_down(alo, blo), div_down(alo, bhi)),
            min(div_down(ahi, blo), div_down(ahi, bhi)),
        )
        hi = max(
            max(div_up(alo, blo), div_up(alo, bhi)),
            max(div_up(ahi, blo), div_up(ahi, bhi)),
        )
        return lo, hi
    if blo == 0.0 and bhi == 0.0:
        return EMPTY
    if alo <= 0.0 <= ahi:
        return -INF, INF
    if ahi < 0.0:
        if blo == 0.0:
            return -INF, div_up(ahi, bhi)
        if bhi == 0.0:
            return div_down(ahi, blo), INF
        return -INF, INF
    if blo == 0.0:
        return div_down(alo, bhi), INF
    if bhi == 0.0:
        return -INF, div_up(alo, blo)
    return -INF, INF


@jit
def sqr(alo: float, ahi: float) -> tuple[float, float]:
    if alo > ahi:
        return EMPTY
    if alo >= 0.0:
        return max(0.0, mul_down(alo, alo)), mul_up(ahi, ahi)
    if ahi <= 0.0:
        return max(0.0, mul_down(ahi, ahi)), mul_up(alo, alo)
    return 0.0, max(mul_up(alo, alo), mul_up(ahi, ahi))


@jit
def sqrt(alo: float, ahi: float) -> tuple[float, float]:
    """Square root of the non-negative part of the interval."""
    if alo > ahi or ahi < 0.0:
        return EMPTY
    return sqrt_down(max(alo, 0.0)), sqrt_up(ahi)


@jit
def bwd_add(
    zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """Narrow x and y under z = x + y."""
    tlo, thi = sub(zlo, zhi, ylo, yhi)
    xlo, xhi = meet(xlo, xhi, tlo, thi)
    tlo, thi = sub(zlo, zhi, xlo, xhi)
    ylo, yhi = meet(ylo, yhi, tlo, thi)
    return xlo, xhi, ylo, yhi


@jit
def bwd_sub(
    zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """Narrow x and y under z = x - y."""
    tlo, thi = add(zlo, zhi, ylo, yhi)
    xlo, xhi = meet(xlo, xhi, tlo, thi)
    tlo, thi = sub(xlo, xhi, zlo, zhi)
    ylo, yhi = meet(ylo, yhi, tlo, thi)
    return xlo, xhi, ylo, yhi


@jit
def bwd_mul(
    zlo: float, zhi: float, xlo: float, xhi: float, ylo: float, yhi: float
) -> tuple[float, float, float, float]:
    """Narrow x and y under z = x * y."""
    if zlo > zhi:
        return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    if not (zlo <= 0.0 <= zhi and ylo <= 0.0 <= yhi):
        tlo, thi = div(zlo, zhi, ylo, yhi)
        xlo, xhi = meet(xlo, xhi, tlo, thi)
    if not (zlo <= 0.0 <= zhi and xlo <= 0.0 <= xhi):
        tlo, thi = div(zlo, zhi, xlo, xhi)
        ylo, yhi = meet(ylo, yhi, tlo, thi)
    return xlo, xhi, ylo, yhi


@jit
def bwd_sqr(zlo: float, zhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """Narrow x under z = x**2: keep the hull of both branches +-sqrt(z)."""
    zlo = max(zlo, 0.0)
    if zlo > zhi or xlo > xhi:
        return EMPTY
    rlo, rhi = sqrt_down(zlo), sqrt_up(zhi)
    plo, phi = meet(xlo, xhi, rlo, rhi)
    nlo, nhi = meet(xlo, xhi, -rhi, -rlo)
    return join(plo, phi, nlo, nhi)


@jit
def bwd_sqrt(zlo: float, zhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """Narrow x under z = sqrt(x), z >= 0."""
    zlo = max(zlo, 0.0)
    if zlo > zhi:
        return EMPTY
    slo, shi = sqr(zlo, zhi)
    return meet(xlo, xhi, slo, shi)


@jit
def width(lo: float, hi: float) -> float:
    """Width rounded up; 0 for an empty interval."""
    if lo > hi:
        return 0.0
    return sub_up(hi, lo)


@jit
def is_finite(lo: float, hi: float) -> bool:
    return math.isfinite(lo) and math.isfinite(hi)
