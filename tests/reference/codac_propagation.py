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
from codac import CtcPolar, Interval

from cuikslam.graph.encoding import OBSERVATION, ODOMETRY
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
