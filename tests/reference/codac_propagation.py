"""Reference propagation: the same chaotic iteration as cuikslam, with codac in a Python loop.

The honest baseline for :func:`cuikslam.narrowing.propagate`: a FIFO queue of factors;
each factor popped is narrowed once with codac intervals (one ``CtcPolar`` call for its
polar relation); every other factor sharing a variable that shrank by more than ``rtol``
of its width is queued again. No tricks: plain Python, one codac contractor per factor
application.

Angles are intersected as plain intervals (no wrapping): that is sound as long as the
log's angles are consistent representatives, as they are in simulated worlds
(``CtcPolar`` itself handles the periodicity of the polar angle).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from codac import CtcPolar, Interval, atan2, cos, sin

from cuikslam.graph.encoding import OBSERVATION, ODOMETRY, RELATIVE, ROTATION
from cuikslam.graph.kinematic_graph import KinematicGraph

__all__ = ["codac_propagate"]


def _shrunk(old_lo: float, old_hi: float, new: Interval, rtol: float) -> bool:
    """True when ``new`` is narrower than [old_lo, old_hi] by more than ``rtol`` of its width
    (the same test as cuikslam's)."""
    old_w = old_hi - old_lo
    new_w = new.ub() - new.lb()
    if old_w == float("inf"):
        return new_w < old_w
    return new_w < old_w * (1.0 - rtol)


def _relative(
    kind: int, row: list[int], dom: list[Interval], polar: CtcPolar
) -> list[tuple[int, Interval]]:
    """One application of a relative pose's factor with codac intervals.

    ROTATION: tb = ta + dtheta, forward and backward. RELATIVE: D = (xb - xa, yb - ya) is
    R(ta) (u, v): the rotation matrix both ways, then the polar form (u, v) = rho
    (cos alpha, sin alpha), D = rho (cos(ta + alpha), sin(ta + alpha)) with two CtcPolar.
    """
    _, ixa, iya, ita, ixb, iyb, itb, iang, ilen = row
    ta = Interval(dom[ita])
    if kind == ROTATION:
        tb, ang = Interval(dom[itb]), Interval(dom[iang])
        tb &= ta + ang
        ta &= tb - ang
        ang &= tb - ta
        return [(ita, ta), (itb, tb), (iang, ang)]
    xa, ya, xb, yb = (Interval(dom[i]) for i in (ixa, iya, ixb, iyb))
    u, v = Interval(dom[iang]), Interval(dom[ilen])
    dx, dy = xb - xa, yb - ya
    for _ in range(10):
        c, s = cos(ta), sin(ta)
        dx &= u * c - v * s
        dy &= u * s + v * c
        u &= dx * c + dy * s
        v &= dy * c - dx * s
        rho, alpha = Interval(0, float("inf")), atan2(v, u)
        u, v, rho, alpha = polar.contract(u, v, rho, alpha)
        phi = ta + alpha
        dx, dy, rho, phi = polar.contract(dx, dy, rho, phi)
        alpha &= phi - ta
        ta &= phi - alpha
        u, v, rho, alpha = polar.contract(u, v, rho, alpha)
        if any(w.is_empty() for w in (dx, dy, u, v, ta)):
            break
    xb &= xa + dx
    xa &= xb - dx
    yb &= ya + dy
    ya &= yb - dy
    return [(ixa, xa), (iya, ya), (ita, ta), (ixb, xb), (iyb, yb), (iang, u), (ilen, v)]


def codac_propagate(
    graph: KinematicGraph, rtol: float = 1e-3
) -> tuple[np.ndarray, np.ndarray, bool, int]:
    """Narrow the graph's initial boxes to the fixpoint of its factors, with codac.

    Returns ``(lo, hi, consistent, applications)``: the narrowed bounds of every variable,
    False when some factor was proven to have no solution (then the bounds are those at
    the moment of the proof), and the number of factor operators applied.
    """
    lo0, hi0 = graph.domains()
    dom = [Interval(float(a), float(b)) for a, b in zip(lo0, hi0, strict=True)]
    table = graph.factor_table().tolist()
    factors_of: list[list[int]] = [[] for _ in dom]  # factors of each variable
    for f, row in enumerate(table):
        for var in row[1:]:
            if var >= 0:
                factors_of[var].append(f)
    polar = CtcPolar()

    queue = deque(range(len(table)))
    queued = [True] * len(table)
    applications = 0
    consistent = True
    while queue:
        f = queue.popleft()
        queued[f] = False
        kind, ixa, iya, ita, ixb, iyb, itb, iang, ilen = table[f]
        applications += 1
        if kind in (RELATIVE, ROTATION):
            new = _relative(kind, table[f], dom, polar)
            if any(v.is_empty() for _, v in new):
                consistent = False
                break
            for var, value in new:
                old = dom[var]
                old_lo, old_hi = old.lb(), old.ub()
                value &= old
                dom[var] = value
                if not _shrunk(old_lo, old_hi, value, rtol):
                    continue
                for g in reversed(factors_of[var]):
                    if g != f and not queued[g]:
                        queue.append(g)
                        queued[g] = True
            continue
        # fresh copies: codac's &= and contract() work in place
        xa, ya, ta = Interval(dom[ixa]), Interval(dom[iya]), Interval(dom[ita])
        xb, yb = Interval(dom[ixb]), Interval(dom[iyb])
        ang, length = Interval(dom[iang]), Interval(dom[ilen])
        if kind == ODOMETRY:
            tb = Interval(dom[itb])
            tb &= ta + ang
            ta &= tb - ang
            ang &= tb - ta
            phi = Interval(tb)
        elif kind == OBSERVATION:
            phi = ta + ang
        else:  # pragma: no cover - no other kind exists
            raise ValueError(f"unknown factor kind {kind}")
        dx = xb - xa
        dy = yb - ya
        length_in, phi_in = Interval(length), Interval(phi)
        dx, dy, length, phi = polar.contract(dx, dy, length, phi)
        length &= length_in  # CtcPolar may return a hair wider than its input
        phi &= phi_in
        xb &= xa + dx
        xa &= xb - dx
        yb &= ya + dy
        ya &= yb - dy
        if kind == ODOMETRY:
            tb &= phi
            new = ((ixa, xa), (iya, ya), (ita, ta), (ixb, xb), (iyb, yb), (itb, tb),
                   (iang, ang), (ilen, length))  # fmt: skip
        else:
            ta &= phi - ang
            ang &= phi - ta
            new = ((ixa, xa), (iya, ya), (ita, ta), (ixb, xb), (iyb, yb), (iang, ang),
                   (ilen, length))  # fmt: skip
        if any(v.is_empty() for _, v in new):
            consistent = False
            break
        for var, value in new:
            old = dom[var]
            old_lo, old_hi = old.lb(), old.ub()
            value &= old
            dom[var] = value
            if not _shrunk(old_lo, old_hi, value, rtol):
                continue
            for g in reversed(factors_of[var]):  # newest first, as cuikslam
                if g != f and not queued[g]:
                    queue.append(g)
                    queued[g] = True
    lo = np.array([v.lb() for v in dom], dtype=np.float64)
    hi = np.array([v.ub() for v in dom], dtype=np.float64)
    return lo, hi, consistent, applications
