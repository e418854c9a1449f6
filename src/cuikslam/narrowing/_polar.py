"""Compiled narrowing operator of the polar relation (x, y) = rho (cos phi, sin phi), rho >= 0.

The relation behind every factor of a kinematic graph: odometry (displacement = distance
along the new heading) and observations (landmark offset = range along heading + bearing).
It chains three sub-operators, each exact for its own sub-relation, and repeats them
until nothing shrinks by more than ``rtol``:

1. the angle relation phi ≡ arg(x, y) (mod 2 pi), without atan2's cut;
2. rho**2 = x**2 + y**2, forward and backward;
3. x = rho cos phi and y = rho sin phi, forward and backward.

Their fixpoint is as tight as the minimal polar contractor of Desrochers and Jaulin
(``tests/test_polar_vs_codac.py`` compares it with codac's ``CtcPolar``).
"""

from __future__ import annotations

from cuikslam._jit import jit
from cuikslam.interval._arith import EMPTY, add, bwd_sqr, div, meet, mul, sqr, sqrt, sub
from cuikslam.interval._periodic import arg_contract, bwd_cos, bwd_sin, cos, sin
from cuikslam.interval._rounding import INF

_EMPTY8 = (EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1])


@jit
def shrunk(old_lo: float, old_hi: float, new_lo: float, new_hi: float, rtol: float) -> bool:
    """True when [new] is narrower than [old] by more than the fraction ``rtol`` of its width."""
    old_w = old_hi - old_lo
    new_w = new_hi - new_lo
    if old_w == INF:
        return new_w < INF
    return new_w < old_w * (1.0 - rtol)


@jit
def polar_contract(
    xlo: float,
    xhi: float,
    ylo: float,
    yhi: float,
    rlo: float,
    rhi: float,
    plo: float,
    phi: float,
    rtol: float,
    max_rounds: int,
) -> tuple[float, float, float, float, float, float, float, float]:
    """Narrow (x, y, rho, phi) under (x, y) = rho (cos phi, sin phi) with rho >= 0.

    ``phi`` is an unwrapped angle interval. Returns the eight narrowed bounds; all empty
    when the relation has no solution in the box.
    """
    rlo = max(rlo, 0.0)
    if xlo > xhi or ylo > yhi or rlo > rhi or plo > phi:
        return _EMPTY8
    for _ in range(max_rounds):
        x0lo, x0hi, y0lo, y0hi, r0lo, r0hi, p0lo, p0hi = xlo, xhi, ylo, yhi, rlo, rhi, plo, phi
        # 1. angle
        if rhi > 0.0:
            xlo, xhi, ylo, yhi, plo, phi = arg_contract(xlo, xhi, ylo, yhi, plo, phi)
            if xlo > xhi:
                return _EMPTY8
        # 2. rho^2 = x^2 + y^2
        x2lo, x2hi = sqr(xlo, xhi)
        y2lo, y2hi = sqr(ylo, yhi)
        slo, shi = add(x2lo, x2hi, y2lo, y2hi)
        r2lo, r2hi = sqr(rlo, rhi)
        slo, shi = meet(slo, shi, r2lo, r2hi)
        if slo > shi:
            return _EMPTY8
        tlo, thi = sqrt(slo, shi)
        rlo, rhi = meet(rlo, rhi, tlo, thi)
        tlo, thi = sub(slo, shi, y2lo, y2hi)
        xlo, xhi = bwd_sqr(tlo, thi, xlo, xhi)
        tlo, thi = sub(slo, shi, x2lo, x2hi)
        ylo, yhi = bwd_sqr(tlo, thi, ylo, yhi)
        if rlo > rhi or xlo > xhi or ylo > yhi:
            return _EMPTY8
        # 3. x = rho cos phi, y = rho sin phi
        clo, chi = cos(plo, phi)
        snlo, snhi = sin(plo, phi)
        tlo, thi = mul(rlo, rhi, clo, chi)
        xlo, xhi = meet(xlo, xhi, tlo, thi)
        tlo, thi = mul(rlo, rhi, snlo, snhi)
        ylo, yhi = meet(ylo, yhi, tlo, thi)
        if xlo > xhi or ylo > yhi:
            return _EMPTY8
        if rlo > 0.0:
            # cos(phi) in x / rho, sin(phi) in y / rho: worth inverting only if they cut
            tlo, thi = div(xlo, xhi, rlo, rhi)
            if tlo > clo or thi < chi:
                clo, chi = meet(clo, chi, tlo, thi)
                plo, phi = bwd_cos(clo, chi, plo, phi)
            tlo, thi = div(ylo, yhi, rlo, rhi)
            if tlo > snlo or thi < snhi:
                snlo, snhi = meet(snlo, snhi, tlo, thi)
                plo, phi = bwd_sin(snlo, snhi, plo, phi)
            if plo > phi:
                return _EMPTY8
        if not (
            shrunk(x0lo, x0hi, xlo, xhi, rtol)
            or shrunk(y0lo, y0hi, ylo, yhi, rtol)
            or shrunk(r0lo, r0hi, rlo, rhi, rtol)
            or shrunk(p0lo, p0hi, plo, phi, rtol)
        ):
            break
    return xlo, xhi, ylo, yhi, rlo, rhi, plo, phi
