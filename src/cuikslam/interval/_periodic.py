"""Compiled interval functions of angles, which are periodic and stored unwrapped.

An angle interval such as ``[5.9, 6.6]`` is kept as it is, never reduced to (-pi, pi]:
narrowing keeps every value that is congruent (mod 2 pi) to an admissible one, so nothing
is lost at the +-pi cut, and an interval at least 2 pi wide means "any angle". The one
building block is :func:`periodic_meet`: the hull of ``X ∩ (A + 2 pi Z)``.
"""

from __future__ import annotations

import math

from cuikslam._jit import jit
from cuikslam.interval._arith import EMPTY, join, meet, mul, sub
from cuikslam.interval._rounding import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    PI_HI,
    PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
    add_down,
    add_up,
    div_down,
    div_up,
    libm_down,
    libm_up,
    mul_down,
    mul_up,
    sub_down,
    sub_up,
)

# Beyond this magnitude an angle carries no usable phase in double precision.
_PHASE_LIMIT = 1.0e12
# The float shortcut for monotone pieces of sin and cos: below this magnitude the
# quotient x / pi is within 1e-9 of its exact value, far inside the margin.
_FAST_LIMIT = 1.0e6
_FAST_MARGIN = 1.0e-6
# periodic_meet's shortcut: X and A together narrower than this (well below 2 pi), and the
# nearest copy's index at least this far from a tie
_NARROW_PAIR = 5.0
_K_MARGIN = 0.05


@jit
def _shift_bounds(k: float) -> tuple[float, float]:
    """An enclosure of 2 pi k for an integer-valued float k."""
    if k >= 0.0:
        return mul_down(k, TWO_PI_LO), mul_up(k, TWO_PI_HI)
    return mul_down(k, TWO_PI_HI), mul_up(k, TWO_PI_LO)


@jit
def periodic_meet_k(
    xlo: float, xhi: float, alo: float, ahi: float
) -> tuple[float, float, float, float]:
    """Hull of ``X ∩ ∪_k [alo + 2πk, ahi + 2πk]`` and the first and last k that meet X.

    Returns ``(lo, hi, k_first, k_last)``; empty when no copy of A meets X. X = (-inf, inf)
    (an angle never narrowed) gives A itself, its representative. When X is half
    unbounded or beyond the phase limit, or A is at least 2 pi wide (any angle), X is
    returned unchanged with ``(k_first, k_last) = (-inf, inf)``.
    """
    if xlo > xhi or alo > ahi:
        return EMPTY[0], EMPTY[1], 1.0, 0.0
    if not (math.isfinite(alo) and math.isfinite(ahi)) or sub_up(ahi, alo) >= TWO_PI_LO:
        return xlo, xhi, -INF, INF
    if xlo == -INF and xhi == INF:
        # any angle: the copy k = 0 is a representative of every admissible heading
        return alo, ahi, 0.0, 0.0
    if not (math.isfinite(xlo) and math.isfinite(xhi)) or max(abs(xlo), abs(xhi)) > _PHASE_LIMIT:
        return xlo, xhi, -INF, INF
    if max(abs(alo), abs(ahi)) > _PHASE_LIMIT:
        # the copies' shifts 2 pi k would be too coarse (k steps by more than 1)
        return xlo, xhi, -INF, INF
    width_x = xhi - xlo
    width_a = ahi - alo
    if width_x + width_a < _NARROW_PAIR:
        # both narrow: only the copy nearest to X can meet it (the others are more than
        # pi - (width_x + width_a) / 2 away), unless the float rounding of the nearest k is
        # in doubt, which the margin on the fractional part rules out
        q = ((xlo + xhi) - (alo + ahi)) / (2.0 * TWO_PI_LO)
        k = math.floor(q + 0.5)
        if abs(q - k) < 0.5 - _K_MARGIN:
            slo, shi = _shift_bounds(k)
            lo = max(xlo, add_down(alo, slo))
            hi = min(xhi, add_up(ahi, shi))
            if lo > hi:
                return EMPTY[0], EMPTY[1], 1.0, 0.0
            return lo, hi, k, k
    # floor/ceil of the float quotients never pass the true first/last k (error << 1);
    # the scans below then find the exact first and last copies that meet X
    k_start = math.floor((xlo - ahi) / TWO_PI_HI)
    k_stop = math.ceil((xhi - alo) / TWO_PI_LO)
    k_first = k_start
    found = False
    while k_first <= min(k_stop, k_start + 8.0):
        slo, shi = _shift_bounds(k_first)
        if add_down(alo, slo) <= xhi and add_up(ahi, shi) >= xlo:
            found = True
            break
        k_first += 1.0
    if not found:
        return EMPTY[0], EMPTY[1], 1.0, 0.0
    k_last = k_stop
    while k_last > k_first:
        slo, shi = _shift_bounds(k_last)
        if add_down(alo, slo) <= xhi and add_up(ahi, shi) >= xlo:
            break
        k_last -= 1.0
    slo, _ = _shift_bounds(k_first)
    _, shi = _shift_bounds(k_last)
    return max(xlo, add_down(alo, slo)), min(xhi, add_up(ahi, shi)), k_first, k_last


@jit
def periodic_meet(xlo: float, xhi: float, alo: float, ahi: float) -> tuple[float, float]:
    """Hull of ``X ∩ (A + 2 pi Z)``: the angles of X congruent to some angle of A."""
    lo, hi, _, _ = periodic_meet_k(xlo, xhi, alo, ahi)
    return lo, hi


@jit
def _cos_down(v: float) -> float:
    return max(-1.0, libm_down(math.cos(v)))


@jit
def _cos_up(v: float) -> float:
    return min(1.0, libm_up(math.cos(v)))


@jit
def _sin_down(v: float) -> float:
    return max(-1.0, libm_down(math.sin(v)))


@jit
def _sin_up(v: float) -> float:
    return min(1.0, libm_up(math.sin(v)))


@jit
def _may_contain(xlo: float, xhi: float, alo: float, ahi: float) -> bool:
    lo, hi = periodic_meet(xlo, xhi, alo, ahi)
    return lo <= hi


@jit
def _same_half_period(xlo: float, xhi: float, offset: float) -> bool:
    """True when [xlo, xhi] surely lies inside one interval (k pi - offset, (k+1) pi - offset).

    A float shortcut that only says True when a margin far larger than its rounding error
    separates both ends from every multiple; otherwise the exact path decides.
    """
    if max(abs(xlo), abs(xhi)) > _FAST_LIMIT:
        return False
    qlo = (xlo + offset) / PI_LO
    qhi = (xhi + offset) / PI_LO
    klo = math.floor(qlo)
    if klo != math.floor(qhi):
        return False
    return qlo - klo > _FAST_MARGIN and klo + 1.0 - qhi > _FAST_MARGIN


@jit
def cos(xlo: float, xhi: float) -> tuple[float, float]:
    if xlo > xhi:
        return EMPTY
    if not (math.isfinite(xlo) and math.isfinite(xhi)) or xhi - xlo >= TWO_PI_LO:
        return -1.0, 1.0
    if max(abs(xlo), abs(xhi)) > _PHASE_LIMIT:
        return -1.0, 1.0
    if _same_half_period(xlo, xhi, 0.0):
        # cos is monotone between consecutive multiples of pi
        a, b = math.cos(xlo), math.cos(xhi)
        return max(-1.0, libm_down(min(a, b))), min(1.0, libm_up(max(a, b)))
    lo = -1.0 if _may_contain(xlo, xhi, PI_LO, PI_HI) else min(_cos_down(xlo), _cos_down(xhi))
    hi = 1.0 if _may_contain(xlo, xhi, 0.0, 0.0) else max(_cos_up(xlo), _cos_up(xhi))
    return lo, hi


@jit
def sin(xlo: float, xhi: float) -> tuple[float, float]:
    if xlo > xhi:
        return EMPTY
    if not (math.isfinite(xlo) and math.isfinite(xhi)) or xhi - xlo >= TWO_PI_LO:
        return -1.0, 1.0
    if max(abs(xlo), abs(xhi)) > _PHASE_LIMIT:
        return -1.0, 1.0
    if _same_half_period(xlo, xhi, HALF_PI_LO):
        # sin is monotone between consecutive odd multiples of pi/2
        a, b = math.sin(xlo), math.sin(xhi)
        return max(-1.0, libm_down(min(a, b))), min(1.0, libm_up(max(a, b)))
    lo = (
        -1.0
        if _may_contain(xlo, xhi, -HALF_PI_HI, -HALF_PI_LO)
        else min(_sin_down(xlo), _sin_down(xhi))
    )
    hi = 1.0 if _may_contain(xlo, xhi, HALF_PI_LO, HALF_PI_HI) else max(_sin_up(xlo), _sin_up(xhi))
    return lo, hi


@jit
def _acos_bounds(ylo: float, yhi: float) -> tuple[float, float]:
    """Enclosure of acos([ylo, yhi]) for -1 <= ylo <= yhi <= 1 (acos is decreasing)."""
    return max(0.0, libm_down(math.acos(yhi))), min(PI_HI, libm_up(math.acos(ylo)))


@jit
def _asin_bounds(ylo: float, yhi: float) -> tuple[float, float]:
    """Enclosure of asin([ylo, yhi]) for -1 <= ylo <= yhi <= 1."""
    return max(-HALF_PI_HI, libm_down(math.asin(ylo))), min(HALF_PI_HI, libm_up(math.asin(yhi)))


@jit
def bwd_cos(ylo: float, yhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """Narrow the angle x under y = cos(x)."""
    ylo, yhi = meet(ylo, yhi, -1.0, 1.0)
    if ylo > yhi or xlo > xhi:
        return EMPTY
    if ylo <= -1.0 and yhi >= 1.0:
        return xlo, xhi
    alo, ahi = _acos_bounds(ylo, yhi)
    plo, phi = periodic_meet(xlo, xhi, alo, ahi)
    nlo, nhi = periodic_meet(xlo, xhi, -ahi, -alo)
    return join(plo, phi, nlo, nhi)


@jit
def bwd_sin(ylo: float, yhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """Narrow the angle x under y = sin(x)."""
    ylo, yhi = meet(ylo, yhi, -1.0, 1.0)
    if ylo > yhi or xlo > xhi:
        return EMPTY
    if ylo <= -1.0 and yhi >= 1.0:
        return xlo, xhi
    alo, ahi = _asin_bounds(ylo, yhi)
    plo, phi = periodic_meet(xlo, xhi, alo, ahi)
    nlo, nhi = periodic_meet(xlo, xhi, sub_down(PI_LO, ahi), sub_up(PI_HI, alo))
    return join(plo, phi, nlo, nhi)


@jit
def _atan2_down(v: float, u: float) -> float:
    """Lower bound of the angle of (u, v) in the closed first quadrant.

    ``+ 0.0`` turns a bound of -0.0 into +0.0: an interval's zero has no sign, but
    ``atan2`` reads it (atan2(0, -0) = pi), which put a vector on the +y axis at pi.
    """
    return max(0.0, libm_down(math.atan2(v + 0.0, u + 0.0)))


@jit
def _atan2_up(v: float, u: float) -> float:
    """Upper bound of the angle of (u, v) in the closed first quadrant (zeros unsigned)."""
    return min(HALF_PI_HI, libm_up(math.atan2(v + 0.0, u + 0.0)))


@jit
def _tan_down(a: float) -> float:
    """Lower bound of tan(a) for 0 <= a < pi/2 (clamped below pi/2)."""
    if a <= 0.0:
        return 0.0
    return max(0.0, libm_down(math.tan(min(a, HALF_PI_LO))))


@jit
def _tan_up(b: float) -> float:
    """Upper bound of tan(b) for 0 <= b; inf when b may reach pi/2."""
    if b >= HALF_PI_LO:
        return INF
    if b <= 0.0:
        return 0.0
    return libm_up(math.tan(b))


@jit
def _narrow_first_quadrant(
    ulo: float, uhi: float, vlo: float, vhi: float, alo: float, ahi: float
) -> tuple[float, float, float, float]:
    """Narrow a box of the closed first quadrant to the points whose angle lies in [alo, ahi].

    Uses v in u * tan([alo, ahi]) and u in v * cot([alo, ahi]), twice.
    """
    tlo = _tan_down(alo)
    thi = _tan_up(ahi)
    # cot(ahi) >= 1 / tan_up(ahi); cot(alo) <= 1 / tan_down(alo)
    clo = 0.0 if thi == INF else div_down(1.0, thi)
    chi = INF if tlo <= 0.0 else div_up(1.0, tlo)
    for _ in range(2):
        vlo = max(vlo, mul_down(ulo, tlo))
        if thi < INF:
            vhi = min(vhi, mul_up(uhi, thi))
        ulo = max(ulo, mul_down(vlo, clo))
        if chi < INF:
            uhi = min(uhi, mul_up(vhi, chi))
        if ulo > uhi or vlo > vhi:
            return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    return ulo, uhi, vlo, vhi


@jit
def arg_contract(
    xlo: float, xhi: float, ylo: float, yhi: float, plo: float, phi: float
) -> tuple[float, float, float, float, float, float]:
    """Narrow (x, y, phi) under phi ≡ angle of the vector (x, y) (mod 2 pi), for (x, y) != 0.

    This is atan2 without its cut: phi may be any unwrapped interval. The box is split
    into its parts in the four closed quadrants; each part is mirrored into the first
    quadrant, where the angle is monotone in each coordinate. When the box contains the
    origin, whose angle is undefined, the origin stays and phi is left as it is; the parts
    (cones from the origin) are still narrowed.
    """
    if xlo > xhi or ylo > yhi or plo > phi:
        return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    origin = xlo <= 0.0 <= xhi and ylo <= 0.0 <= yhi
    if origin and not (phi - plo < TWO_PI_LO):
        return xlo, xhi, ylo, yhi, plo, phi  # any angle, and the origin: nothing to narrow
    oxlo, oxhi, oylo, oyhi, oplo, ophi = (
        EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1],
    )  # fmt: skip
    for q in range(4):
        # mirror: u = sx * x, v = sy * y; quadrant q: sx, sy
        sx = 1.0 if q == 0 or q == 3 else -1.0
        sy = 1.0 if q <= 1 else -1.0
        if sx > 0:
            ulo, uhi = max(xlo, 0.0), xhi
        else:
            ulo, uhi = max(-xhi, 0.0), -xlo
        if sy > 0:
            vlo, vhi = max(ylo, 0.0), yhi
        else:
            vlo, vhi = max(-yhi, 0.0), -ylo
        if ulo > uhi or vlo > vhi or (uhi <= 0.0 and vhi <= 0.0):
            continue
        psi_lo = _atan2_down(vlo, uhi)
        psi_hi = _atan2_up(vhi, ulo)
        # the angle phi of the part, as an arc: q0 psi, q1 pi-psi, q2 psi-pi, q3 -psi
        if q == 0:
            alo, ahi = psi_lo, psi_hi
        elif q == 1:
            alo, ahi = sub_down(PI_LO, psi_hi), sub_up(PI_HI, psi_lo)
        elif q == 2:
            alo, ahi = sub_down(psi_lo, PI_HI), sub_up(psi_hi, PI_LO)
        else:
            alo, ahi = -psi_hi, -psi_lo
        qlo, qhi, k_first, k_last = periodic_meet_k(plo, phi, alo, ahi)
        if qlo > qhi:
            continue
        if k_first == k_last:
            # one copy of the arc: map phi - 2 pi k back to psi and narrow the part
            slo, shi = mul(k_first, k_first, TWO_PI_LO, TWO_PI_HI)
            rlo, rhi = sub(qlo, qhi, slo, shi)
            if q == 0:
                blo, bhi = rlo, rhi
            elif q == 1:
                blo, bhi = sub_down(PI_LO, rhi), sub_up(PI_HI, rlo)
            elif q == 2:
                blo, bhi = add_down(rlo, PI_LO), add_up(rhi, PI_HI)
            else:
                blo, bhi = -rhi, -rlo
            blo, bhi = max(blo, psi_lo), min(bhi, psi_hi)
            ulo, uhi, vlo, vhi = _narrow_first_quadrant(ulo, uhi, vlo, vhi, blo, bhi)
            if ulo > uhi:
                continue
        if sx > 0:
            pxlo, pxhi = ulo, uhi
        else:
            pxlo, pxhi = -uhi, -ulo
        if sy > 0:
            pylo, pyhi = vlo, vhi
        else:
            pylo, pyhi = -vhi, -vlo
        oxlo, oxhi = join(oxlo, oxhi, pxlo, pxhi)
        oylo, oyhi = join(oylo, oyhi, pylo, pyhi)
        oplo, ophi = join(oplo, ophi, qlo, qhi)
    if origin:
        oxlo, oxhi = join(oxlo, oxhi, 0.0, 0.0)
        oylo, oyhi = join(oylo, oyhi, 0.0, 0.0)
        return oxlo, oxhi, oylo, oyhi, plo, phi
    if oxlo > oxhi:
        return EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1], EMPTY[0], EMPTY[1]
    return oxlo, oxhi, oylo, oyhi, oplo, ophi


@jit
def atan2(ylo: float, yhi: float, xlo: float, xhi: float) -> tuple[float, float]:
    """Enclosure of the principal angle atan2(y, x) in [-pi, pi] (the classic, cut function).

    Prefer :func:`arg_contract` with an unwrapped angle interval: it has no cut.
    """
    if xlo > xhi or ylo > yhi:
        return EMPTY
    if xlo <= 0.0 <= xhi and ylo <= 0.0 <= yhi:
        return -PI_HI, PI_HI
    if xhi < 0.0 and ylo < 0.0 <= yhi:
        return -PI_HI, PI_HI
    _, _, _, _, lo, hi = arg_contract(xlo, xhi, ylo, yhi, -PI_HI, PI_HI)
    return lo, hi
