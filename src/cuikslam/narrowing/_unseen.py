"""Compiled narrowing operator of negative information: a landmark the sensor did not see.

If the robot at pose a would have seen every landmark within distance R and inside its
field of view, a landmark b that pose a did not observe satisfies

    |b - a| >= R   or   bearing(b - a) - theta_a  lies outside the field of view.

The operator narrows the offset (dx, dy) and theta_a under each alternative and keeps
the hull of the two results; when both are empty the hypothesis is impossible.
"""

from __future__ import annotations

from cuikslam._jit import jit
from cuikslam.interval._arith import EMPTY, add, bwd_sqr, join, meet, sqr, sub
from cuikslam.interval._periodic import arg_contract, periodic_meet

_EMPTY6 = (EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1])


@jit
def _far(
    dxlo: float, dxhi: float, dylo: float, dyhi: float, r_lo: float
) -> tuple[float, float, float, float]:
    """Narrow (dx, dy) under dx**2 + dy**2 >= r_lo**2."""
    if r_lo <= 0.0:
        return dxlo, dxhi, dylo, dyhi
    x2lo, x2hi = sqr(dxlo, dxhi)
    y2lo, y2hi = sqr(dylo, dyhi)
    slo, shi = add(x2lo, x2hi, y2lo, y2hi)
    r2lo, _ = sqr(r_lo, r_lo)
    slo, shi = meet(slo, shi, r2lo, shi)
    if slo > shi:
        return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    tlo, thi = sub(slo, shi, y2lo, y2hi)
    dxlo, dxhi = bwd_sqr(tlo, thi, dxlo, dxhi)
    tlo, thi = sub(slo, shi, x2lo, x2hi)
    dylo, dyhi = bwd_sqr(tlo, thi, dylo, dyhi)
    if dxlo > dxhi or dylo > dyhi:
        return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    return dxlo, dxhi, dylo, dyhi


@jit
def unseen_contract(
    dxlo: float,
    dxhi: float,
    dylo: float,
    dyhi: float,
    talo: float,
    tahi: float,
    arc_lo: float,
    arc_hi: float,
    r_lo: float,
) -> tuple[float, float, float, float, float, float]:
    """Narrow (dx, dy, theta_a) under "|d| >= r_lo or bearing of d in theta_a + [arc_lo, arc_hi]".

    ``[arc_lo, arc_hi]`` are the bearings outside the field of view (empty for a sensor
    that sees all around). Returns all-empty bounds when neither alternative is possible.
    """
    fxlo, fxhi, fylo, fyhi = _far(dxlo, dxhi, dylo, dyhi, r_lo)
    ftlo, fthi = talo, tahi
    if fxlo > fxhi:
        ftlo, fthi = EMPTY
    oxlo, oxhi, oylo, oyhi, otlo, othi = _EMPTY6
    if arc_lo <= arc_hi and not (dxlo <= 0.0 <= dxhi and dylo <= 0.0 <= dyhi):
        plo, phi = add(talo, tahi, arc_lo, arc_hi)
        oxlo, oxhi, oylo, oyhi, plo, phi = arg_contract(dxlo, dxhi, dylo, dyhi, plo, phi)
        if oxlo <= oxhi:
            tlo, thi = sub(plo, phi, arc_lo, arc_hi)
            otlo, othi = periodic_meet(talo, tahi, tlo, thi)
            if otlo > othi:
                oxlo, oxhi, oylo, oyhi = EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    elif arc_lo <= arc_hi:
        oxlo, oxhi, oylo, oyhi, otlo, othi = dxlo, dxhi, dylo, dyhi, talo, tahi
    xlo, xhi = join(fxlo, fxhi, oxlo, oxhi)
    ylo, yhi = join(fylo, fyhi, oylo, oyhi)
    tlo, thi = join(ftlo, fthi, otlo, othi)
    if xlo > xhi or ylo > yhi or tlo > thi:
        return _EMPTY6
    return xlo, xhi, ylo, yhi, tlo, thi
