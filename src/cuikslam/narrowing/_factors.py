"""Compiled narrowing operators of the factor kinds, over array-encoded graphs.

See :mod:`cuikslam.graph.encoding` for the layout of variables and factor rows. Every
quantity of a factor is narrowed, headings and measurements included.
"""

from __future__ import annotations

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import (
    ANGLE,
    KIND,
    LENGTH,
    NO_FACTOR,
    ODOMETRY,
    RELATIVE,
    ROTATION,
    TA,
    TB,
    UNSEEN,
    XA,
    XB,
    YA,
    YB,
)
from cuikslam.interval._arith import add, meet, sub
from cuikslam.interval._periodic import periodic_meet
from cuikslam.interval._rounding import INF
from cuikslam.narrowing._polar import polar_contract, shrunk
from cuikslam.narrowing._relative import relative_contract
from cuikslam.narrowing._unseen import unseen_contract

EMPTY_FACTOR = -1
MEMORY_WIDTH = 6
"""Auxiliary intervals remembered per factor: dx, dy, phi as (lo, hi) pairs."""
NOT_AT_FIXPOINT = 1 << 8
"""Mask bit: the factor still shrank in its last round (apply it again)."""


@jit
def _translate(
    alo: float, ahi: float, blo: float, bhi: float, dlo: float, dhi: float
) -> tuple[float, float, float, float]:
    """Narrow a and b under b = a + d."""
    tlo, thi = add(alo, ahi, dlo, dhi)
    blo, bhi = meet(blo, bhi, tlo, thi)
    tlo, thi = sub(blo, bhi, dlo, dhi)
    alo, ahi = meet(alo, ahi, tlo, thi)
    return alo, ahi, blo, bhi


@jit
def _rotate(
    alo: float, ahi: float, blo: float, bhi: float, dlo: float, dhi: float
) -> tuple[float, float, float, float, float, float]:
    """Narrow the angles a, b, d under b ≡ a + d (mod 2 pi)."""
    tlo, thi = add(alo, ahi, dlo, dhi)
    blo, bhi = periodic_meet(blo, bhi, tlo, thi)
    tlo, thi = sub(blo, bhi, dlo, dhi)
    alo, ahi = periodic_meet(alo, ahi, tlo, thi)
    tlo, thi = sub(blo, bhi, alo, ahi)
    dlo, dhi = periodic_meet(dlo, dhi, tlo, thi)
    return alo, ahi, blo, bhi, dlo, dhi


@jit
def fresh_memory(n_factors: int) -> np.ndarray:
    """Per-factor memory of the auxiliary intervals (dx, dy, phi), all unbounded."""
    memory = np.empty((n_factors, MEMORY_WIDTH))
    memory[:, 0::2] = -INF
    memory[:, 1::2] = INF
    return memory


@jit
def narrow_factor(
    lo: np.ndarray, hi: np.ndarray, row: np.ndarray, rtol: float, max_rounds: int
) -> int:
    """Apply the narrowing operator of one factor once, with no memory of earlier ones."""
    return narrow_factor_memo(lo, hi, row, rtol, max_rounds, fresh_memory(1)[0])


@jit
def narrow_factor_memo(
    lo: np.ndarray,
    hi: np.ndarray,
    row: np.ndarray,
    rtol: float,
    max_rounds: int,
    memory: np.ndarray,
) -> int:
    """Apply the narrowing operator of one factor to ``lo``/``hi`` in place.

    ``memory`` holds this factor's auxiliary intervals from its earlier applications in
    the same propagation: the offset (dx, dy) = (xb - xa, yb - ya) and, for observations,
    phi = ta + bearing. The polar operator narrows them beyond what xb - xa recomputed
    from the boxes gives, so keeping them makes repeated applications reach the polar
    operator's own fixpoint. Each stays an enclosure of its true value, so this is sound.

    Repeats the factor's sub-operators until no variable shrinks by more than ``rtol``
    (at most ``max_rounds`` times). Returns a bit mask of the slots (bit s for column
    s + 1) that shrank by more than ``rtol``, plus ``NOT_AT_FIXPOINT`` when the rounds ran
    out while it still shrank, or ``EMPTY_FACTOR`` when the factor has no solution in the
    box (then nothing is written).
    """
    kind = row[KIND]
    if kind == NO_FACTOR:
        return 0
    if kind == UNSEEN:
        return _narrow_unseen(lo, hi, row, rtol)
    if kind == ROTATION:
        return _narrow_rotation(lo, hi, row, rtol)
    if kind == RELATIVE:
        return _narrow_relative(lo, hi, row, rtol, max_rounds, memory)
    ixa, iya, ita, ixb, iyb = row[XA], row[YA], row[TA], row[XB], row[YB]
    itb, iang, ilen = row[TB], row[ANGLE], row[LENGTH]
    xalo, xahi, yalo, yahi, talo, tahi = lo[ixa], hi[ixa], lo[iya], hi[iya], lo[ita], hi[ita]
    xblo, xbhi, yblo, ybhi = lo[ixb], hi[ixb], lo[iyb], hi[iyb]
    anglo, anghi, lenlo, lenhi = lo[iang], hi[iang], lo[ilen], hi[ilen]
    tblo, tbhi = 0.0, 0.0
    if kind == ODOMETRY:
        tblo, tbhi = lo[itb], hi[itb]
    converged = False
    for _ in range(max_rounds):
        before = (xalo, xahi, yalo, yahi, talo, tahi, xblo, xbhi, yblo, ybhi, tblo, tbhi,
                  anglo, anghi, lenlo, lenhi)  # fmt: skip
        if kind == ODOMETRY:
            talo, tahi, tblo, tbhi, anglo, anghi = _rotate(talo, tahi, tblo, tbhi, anglo, anghi)
            if talo > tahi or tblo > tbhi or anglo > anghi:
                return EMPTY_FACTOR
            plo, phi = tblo, tbhi
        else:
            plo, phi = add(talo, tahi, anglo, anghi)
            # congruence, not equality: ta may have taken another representative since
            plo, phi = periodic_meet(plo, phi, memory[4], memory[5])
        dxlo, dxhi = sub(xblo, xbhi, xalo, xahi)
        dxlo, dxhi = meet(dxlo, dxhi, memory[0], memory[1])
        dylo, dyhi = sub(yblo, ybhi, yalo, yahi)
        dylo, dyhi = meet(dylo, dyhi, memory[2], memory[3])
        if dxlo > dxhi or dylo > dyhi or plo > phi:
            return EMPTY_FACTOR
        d_before = (dxlo, dxhi, dylo, dyhi)
        dxlo, dxhi, dylo, dyhi, lenlo, lenhi, plo, phi = polar_contract(
            dxlo, dxhi, dylo, dyhi, lenlo, lenhi, plo, phi, rtol, max_rounds
        )
        if dxlo > dxhi:
            return EMPTY_FACTOR
        memory[0], memory[1], memory[2], memory[3] = dxlo, dxhi, dylo, dyhi
        if kind != ODOMETRY:
            memory[4], memory[5] = plo, phi
        xalo, xahi, xblo, xbhi = _translate(xalo, xahi, xblo, xbhi, dxlo, dxhi)
        yalo, yahi, yblo, ybhi = _translate(yalo, yahi, yblo, ybhi, dylo, dyhi)
        if kind == ODOMETRY:
            tblo, tbhi = plo, phi
        else:
            # phi = ta + bearing
            tlo, thi = sub(plo, phi, anglo, anghi)
            talo, tahi = periodic_meet(talo, tahi, tlo, thi)
            tlo, thi = sub(plo, phi, talo, tahi)
            anglo, anghi = periodic_meet(anglo, anghi, tlo, thi)
        if xalo > xahi or yalo > yahi or xblo > xbhi or yblo > ybhi or talo > tahi:
            return EMPTY_FACTOR
        if anglo > anghi:
            return EMPTY_FACTOR
        if not (
            shrunk(before[0], before[1], xalo, xahi, rtol)
            or shrunk(before[2], before[3], yalo, yahi, rtol)
            or shrunk(before[4], before[5], talo, tahi, rtol)
            or shrunk(before[6], before[7], xblo, xbhi, rtol)
            or shrunk(before[8], before[9], yblo, ybhi, rtol)
            or shrunk(before[10], before[11], tblo, tbhi, rtol)
            or shrunk(before[12], before[13], anglo, anghi, rtol)
            or shrunk(before[14], before[15], lenlo, lenhi, rtol)
            or shrunk(d_before[0], d_before[1], dxlo, dxhi, rtol)
            or shrunk(d_before[2], d_before[3], dylo, dyhi, rtol)
        ):
            converged = True
            break
    mask = 0 if converged else NOT_AT_FIXPOINT
    mask |= _store(lo, hi, ixa, xalo, xahi, rtol) << 0
    mask |= _store(lo, hi, iya, yalo, yahi, rtol) << 1
    mask |= _store(lo, hi, ita, talo, tahi, rtol) << 2
    mask |= _store(lo, hi, ixb, xblo, xbhi, rtol) << 3
    mask |= _store(lo, hi, iyb, yblo, ybhi, rtol) << 4
    if kind == ODOMETRY:
        mask |= _store(lo, hi, itb, tblo, tbhi, rtol) << 5
    mask |= _store(lo, hi, iang, anglo, anghi, rtol) << 6
    mask |= _store(lo, hi, ilen, lenlo, lenhi, rtol) << 7
    return mask


@jit
def _narrow_rotation(lo: np.ndarray, hi: np.ndarray, row: np.ndarray, rtol: float) -> int:
    """The ROTATION factor: tb ≡ ta + angle (mod 2 pi)."""
    ita, itb, iang = row[TA], row[TB], row[ANGLE]
    talo, tahi, tblo, tbhi, anglo, anghi = _rotate(
        lo[ita], hi[ita], lo[itb], hi[itb], lo[iang], hi[iang]
    )
    if talo > tahi or tblo > tbhi or anglo > anghi:
        return EMPTY_FACTOR
    mask = _store(lo, hi, ita, talo, tahi, rtol) << 2
    mask |= _store(lo, hi, itb, tblo, tbhi, rtol) << 5
    mask |= _store(lo, hi, iang, anglo, anghi, rtol) << 6
    return mask


@jit
def _narrow_relative(
    lo: np.ndarray,
    hi: np.ndarray,
    row: np.ndarray,
    rtol: float,
    max_rounds: int,
    memory: np.ndarray,
) -> int:
    """The RELATIVE factor: (xb - xa, yb - ya) = R(ta) (dx, dy); dx, dy in the angle and
    length slots. ``memory`` keeps the world offset (xb - xa, yb - ya) and its direction."""
    ixa, iya, ita, ixb, iyb = row[XA], row[YA], row[TA], row[XB], row[YB]
    idx, idy = row[ANGLE], row[LENGTH]
    xalo, xahi, yalo, yahi, talo, tahi = lo[ixa], hi[ixa], lo[iya], hi[iya], lo[ita], hi[ita]
    xblo, xbhi, yblo, ybhi = lo[ixb], hi[ixb], lo[iyb], hi[iyb]
    ulo, uhi, vlo, vhi = lo[idx], hi[idx], lo[idy], hi[idy]
    converged = False
    for _ in range(max_rounds):
        before = (xalo, xahi, yalo, yahi, talo, tahi, xblo, xbhi, yblo, ybhi, ulo, uhi, vlo, vhi)
        dxlo, dxhi = sub(xblo, xbhi, xalo, xahi)
        dxlo, dxhi = meet(dxlo, dxhi, memory[0], memory[1])
        dylo, dyhi = sub(yblo, ybhi, yalo, yahi)
        dylo, dyhi = meet(dylo, dyhi, memory[2], memory[3])
        if dxlo > dxhi or dylo > dyhi:
            return EMPTY_FACTOR
        d_before = (dxlo, dxhi, dylo, dyhi)
        dxlo, dxhi, dylo, dyhi, talo, tahi, ulo, uhi, vlo, vhi, plo, phi = relative_contract(
            dxlo, dxhi, dylo, dyhi, talo, tahi, ulo, uhi, vlo, vhi, memory[4], memory[5],
            rtol, max_rounds,
        )  # fmt: skip
        if dxlo > dxhi:
            return EMPTY_FACTOR
        memory[0], memory[1], memory[2], memory[3] = dxlo, dxhi, dylo, dyhi
        memory[4], memory[5] = plo, phi
        xalo, xahi, xblo, xbhi = _translate(xalo, xahi, xblo, xbhi, dxlo, dxhi)
        yalo, yahi, yblo, ybhi = _translate(yalo, yahi, yblo, ybhi, dylo, dyhi)
        if xalo > xahi or yalo > yahi or xblo > xbhi or yblo > ybhi:
            return EMPTY_FACTOR
        if not (
            shrunk(before[0], before[1], xalo, xahi, rtol)
            or shrunk(before[2], before[3], yalo, yahi, rtol)
            or shrunk(before[4], before[5], talo, tahi, rtol)
            or shrunk(before[6], before[7], xblo, xbhi, rtol)
            or shrunk(before[8], before[9], yblo, ybhi, rtol)
            or shrunk(before[10], before[11], ulo, uhi, rtol)
            or shrunk(before[12], before[13], vlo, vhi, rtol)
            or shrunk(d_before[0], d_before[1], dxlo, dxhi, rtol)
            or shrunk(d_before[2], d_before[3], dylo, dyhi, rtol)
        ):
            converged = True
            break
    mask = 0 if converged else NOT_AT_FIXPOINT
    mask |= _store(lo, hi, ixa, xalo, xahi, rtol) << 0
    mask |= _store(lo, hi, iya, yalo, yahi, rtol) << 1
    mask |= _store(lo, hi, ita, talo, tahi, rtol) << 2
    mask |= _store(lo, hi, ixb, xblo, xbhi, rtol) << 3
    mask |= _store(lo, hi, iyb, yblo, ybhi, rtol) << 4
    mask |= _store(lo, hi, idx, ulo, uhi, rtol) << 6
    mask |= _store(lo, hi, idy, vlo, vhi, rtol) << 7
    return mask


@jit
def _narrow_unseen(lo: np.ndarray, hi: np.ndarray, row: np.ndarray, rtol: float) -> int:
    """The UNSEEN factor: narrow pose a and landmark b (angle and length slots are constants;
    no angle slot, -1, for a sensor that sees all around: no bearing is out of view)."""
    ixa, iya, ita, ixb, iyb = row[XA], row[YA], row[TA], row[XB], row[YB]
    dxlo, dxhi = sub(lo[ixb], hi[ixb], lo[ixa], hi[ixa])
    dylo, dyhi = sub(lo[iyb], hi[iyb], lo[iya], hi[iya])
    arc_lo, arc_hi = INF, -INF  # the empty arc
    if row[ANGLE] >= 0:
        arc_lo, arc_hi = lo[row[ANGLE]], hi[row[ANGLE]]
    dxlo, dxhi, dylo, dyhi, talo, tahi = unseen_contract(
        dxlo, dxhi, dylo, dyhi, lo[ita], hi[ita], arc_lo, arc_hi, lo[row[LENGTH]]
    )
    if dxlo > dxhi:
        return EMPTY_FACTOR
    xalo, xahi, xblo, xbhi = _translate(lo[ixa], hi[ixa], lo[ixb], hi[ixb], dxlo, dxhi)
    yalo, yahi, yblo, ybhi = _translate(lo[iya], hi[iya], lo[iyb], hi[iyb], dylo, dyhi)
    if xalo > xahi or xblo > xbhi or yalo > yahi or yblo > ybhi:
        return EMPTY_FACTOR
    mask = 0
    mask |= _store(lo, hi, ixa, xalo, xahi, rtol) << 0
    mask |= _store(lo, hi, iya, yalo, yahi, rtol) << 1
    mask |= _store(lo, hi, ita, talo, tahi, rtol) << 2
    mask |= _store(lo, hi, ixb, xblo, xbhi, rtol) << 3
    mask |= _store(lo, hi, iyb, yblo, ybhi, rtol) << 4
    return mask


@jit
def _store(
    lo: np.ndarray, hi: np.ndarray, i: int, new_lo: float, new_hi: float, rtol: float
) -> int:
    """Write a narrowed interval back (never widening); 1 when it shrank by more than rtol."""
    old_lo, old_hi = lo[i], hi[i]
    new_lo = max(new_lo, old_lo)
    new_hi = min(new_hi, old_hi)
    lo[i] = new_lo
    hi[i] = new_hi
    return 1 if shrunk(old_lo, old_hi, new_lo, new_hi, rtol) else 0
