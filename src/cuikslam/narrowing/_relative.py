"""Compiled narrowing operator of a rigid displacement: (Dx, Dy) = R(t) (u, v).

The translation of a relative pose: the world offset D = (xb - xa, yb - ya) between two
poses is the measured offset d = (u, v), given in the frame of pose a, rotated by its
heading t. Two sub-operators, each sound, are repeated until nothing shrinks by more
than ``rtol``:

1. the rotation matrix, forward and backward: D = R(t) d and d = R(-t) D. Exact for a
   point heading, so a box measurement stays a box (no polar rounding of its corners);
2. the polar form, which keeps the correlation the matrix form loses when t is an
   interval: d = rho (cos alpha, sin alpha) and D = rho (cos phi, sin phi) with
   phi ≡ t + alpha (mod 2 pi), through :func:`~cuikslam.narrowing._polar.polar_contract`.
   This is also what narrows the heading t: phi - alpha.

With a point d this is the turn-then-drive relation of an odometry factor (alpha the
turn, rho the distance), narrowed by the same polar operator.
"""

from __future__ import annotations

import math

from cuikslam._jit import jit
from cuikslam.interval._arith import EMPTY, add, meet, mul, sub
from cuikslam.interval._periodic import cos, periodic_meet, sin
from cuikslam.interval._rounding import INF, PI_HI, add_down, add_up
from cuikslam.narrowing._polar import polar_contract, shrunk

_EMPTY12 = (EMPTY[0], EMPTY[1]) * 6


@jit
def _rotate_vector(
    ulo: float, uhi: float, vlo: float, vhi: float, clo: float, chi: float, slo: float, shi: float
) -> tuple[float, float, float, float]:
    """Enclosure of R(t) (u, v) = (u c - v s, u s + v c) with c = cos t, s = sin t."""
    alo, ahi = mul(ulo, uhi, clo, chi)
    blo, bhi = mul(vlo, vhi, slo, shi)
    xlo, xhi = sub(alo, ahi, blo, bhi)
    alo, ahi = mul(ulo, uhi, slo, shi)
    blo, bhi = mul(vlo, vhi, clo, chi)
    ylo, yhi = add(alo, ahi, blo, bhi)
    return xlo, xhi, ylo, yhi


@jit
def relative_contract(
    dxlo: float,
    dxhi: float,
    dylo: float,
    dyhi: float,
    tlo: float,
    thi: float,
    ulo: float,
    uhi: float,
    vlo: float,
    vhi: float,
    plo: float,
    phi: float,
    rtol: float,
    max_rounds: int,
) -> tuple[
    float, float, float, float, float, float, float, float, float, float, float, float
]:  # fmt: skip
    """Narrow (Dx, Dy, t, u, v) under (Dx, Dy) = R(t) (u, v); ``t`` is an unwrapped heading.

    ``[plo, phi]`` encloses the direction of D known so far (``(-inf, inf)`` for none).
    Returns the narrowed ``(Dx, Dy, t, u, v, direction of D)`` bounds; all empty when the
    relation has no solution in the box.
    """
    for _ in range(max_rounds):
        before = (dxlo, dxhi, dylo, dyhi, tlo, thi, ulo, uhi, vlo, vhi)
        # 1. D = R(t) d and d = R(-t) D
        clo, chi = cos(tlo, thi)
        slo, shi = sin(tlo, thi)
        xlo, xhi, ylo, yhi = _rotate_vector(ulo, uhi, vlo, vhi, clo, chi, slo, shi)
        dxlo, dxhi = meet(dxlo, dxhi, xlo, xhi)
        dylo, dyhi = meet(dylo, dyhi, ylo, yhi)
        if dxlo > dxhi or dylo > dyhi:
            return _EMPTY12
        xlo, xhi, ylo, yhi = _rotate_vector(dxlo, dxhi, dylo, dyhi, clo, chi, -shi, -slo)
        ulo, uhi = meet(ulo, uhi, xlo, xhi)
        vlo, vhi = meet(vlo, vhi, ylo, yhi)
        if ulo > uhi or vlo > vhi:
            return _EMPTY12
        # 2. polar form: alpha = direction of d, phi = direction of D = t + alpha
        alo, ahi = sub(plo, phi, tlo, thi)
        if not (ahi - alo < 6.0):
            # any direction: a window of width > 2 pi centred on d's middle direction,
            # which d's directions (an arc narrower than pi) meet once
            centre = math.atan2(0.5 * (vlo + vhi), 0.5 * (ulo + uhi))
            if not math.isfinite(centre):
                centre = 0.0
            alo, ahi = add_down(centre, -PI_HI), add_up(centre, PI_HI)
        ulo, uhi, vlo, vhi, rlo, rhi, alo, ahi = polar_contract(
            ulo, uhi, vlo, vhi, 0.0, INF, alo, ahi, rtol, max_rounds
        )
        if ulo > uhi:
            return _EMPTY12
        qlo, qhi = add(tlo, thi, alo, ahi)
        plo, phi = periodic_meet(plo, phi, qlo, qhi)
        if plo > phi:
            return _EMPTY12
        dxlo, dxhi, dylo, dyhi, rlo, rhi, plo, phi = polar_contract(
            dxlo, dxhi, dylo, dyhi, rlo, rhi, plo, phi, rtol, max_rounds
        )
        if dxlo > dxhi:
            return _EMPTY12
        qlo, qhi = sub(plo, phi, tlo, thi)
        alo, ahi = periodic_meet(alo, ahi, qlo, qhi)
        if alo > ahi:
            return _EMPTY12
        qlo, qhi = sub(plo, phi, alo, ahi)
        tlo, thi = periodic_meet(tlo, thi, qlo, qhi)
        if tlo > thi:
            return _EMPTY12
        ulo, uhi, vlo, vhi, rlo, rhi, alo, ahi = polar_contract(
            ulo, uhi, vlo, vhi, rlo, rhi, alo, ahi, rtol, max_rounds
        )
        if ulo > uhi:
            return _EMPTY12
        if not (
            shrunk(before[0], before[1], dxlo, dxhi, rtol)
            or shrunk(before[2], before[3], dylo, dyhi, rtol)
            or shrunk(before[4], before[5], tlo, thi, rtol)
            or shrunk(before[6], before[7], ulo, uhi, rtol)
            or shrunk(before[8], before[9], vlo, vhi, rtol)
        ):
            break
    return dxlo, dxhi, dylo, dyhi, tlo, thi, ulo, uhi, vlo, vhi, plo, phi
