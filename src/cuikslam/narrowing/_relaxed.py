"""Compiled q-relaxed intersection of observation factors that may be outliers.

A *relaxed member* is an ``OBSERVATION`` row that may be an outlier: its interval may miss
the truth. Each member computes its own contraction of its pose (or sensor pose) and
landmark variables from the current box, without writing them. For a variable v touched
by k members of which at most q may be outliers, at least k - q of those contractions
contain the truth's value, so v may be narrowed to the (k - q)-th smallest lower bound
and the (k - q)-th largest upper bound (the q-relaxed intersection); a member without
solution in the box contains nothing. Only a member's own measurement variables (bearing
and range, touched by no other factor) are written by it directly.

Headings: while a heading's box is narrower than 2 pi, the true heading has one
representative in it, every member's contraction (stored inside the box) holds that one,
and the order statistics above apply. A wider box means "any heading": the members' arcs
are then counted on the circle (:func:`circular_meet`), and the box becomes the shortest
arc holding every angle that at least k - q of them cover (a heading box means the truth
modulo 2 pi), widened by ``ARC_SLACK`` for the rounding of the reduction modulo 2 pi.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam._jit import jit
from cuikslam.graph.encoding import ANGLE, LENGTH, OBSERVATION, TA, XA, XB, YA, YB
from cuikslam.narrowing._factors import EMPTY_FACTOR, fresh_memory, narrow_factor_memo
from cuikslam.narrowing._polar import shrunk

SHARED_SLOTS = (XA, YA, TA, XB, YB)
"""Columns of a member's row naming variables that other factors share."""
ANGLE_MARGIN = 6.28
"""A heading box at most this wide (below 2 pi) holds one representative of the truth."""
ARC_SLACK = 1e-9
"""Widening of every arc reduced modulo 2 pi (far above the rounding of the reduction for
angles below ``ARC_LIMIT``)."""
ARC_LIMIT = 1e6
"""Headings beyond this magnitude are not narrowed on the circle."""
TWO_PI = 2.0 * math.pi
RELAXED_CONSISTENT = 0
RELAXED_INCONSISTENT = 1

_LOCAL_ROW = np.array([OBSERVATION, 0, 1, 2, 3, 4, -1, 5, 6], dtype=np.int64)


@jit
def member_contractions(
    lo: np.ndarray,
    hi: np.ndarray,
    rows: np.ndarray,
    active: np.ndarray,
    rtol: float,
    max_rounds: int,
    out_lo: np.ndarray,
    out_hi: np.ndarray,
    empty: np.ndarray,
    write_measurements: bool,
) -> int:
    """Each active member's contraction of its shared variables, from the box ``lo``/``hi``.

    ``out_lo[m]``/``out_hi[m]`` receive member m's bounds of the variables in its
    ``SHARED_SLOTS`` columns; ``empty[m]`` is True when the member has no solution in the
    box (or is inactive). With ``write_measurements`` the member's narrowed bearing and
    range are written back. Returns the number of members without solution.
    """
    local_lo = np.empty(7)
    local_hi = np.empty(7)
    row = _LOCAL_ROW.copy()
    n_empty = 0
    for m in range(rows.shape[0]):
        if not active[m]:
            empty[m] = True
            continue
        r = rows[m]
        for j in range(5):  # columns XA, YA, TA, XB, YB are 1..5
            local_lo[j] = lo[r[1 + j]]
            local_hi[j] = hi[r[1 + j]]
        local_lo[5], local_hi[5] = lo[r[ANGLE]], hi[r[ANGLE]]
        local_lo[6], local_hi[6] = lo[r[LENGTH]], hi[r[LENGTH]]
        mask = narrow_factor_memo(local_lo, local_hi, row, rtol, max_rounds, fresh_memory(1)[0])
        if mask == EMPTY_FACTOR:
            empty[m] = True
            n_empty += 1
            continue
        empty[m] = False
        for j in range(5):
            out_lo[m, j] = local_lo[j]
            out_hi[m, j] = local_hi[j]
        if write_measurements:
            a, b = r[ANGLE], r[LENGTH]
            lo[a], hi[a] = max(lo[a], local_lo[5]), min(hi[a], local_hi[5])
            lo[b], hi[b] = max(lo[b], local_lo[6]), min(hi[b], local_hi[6])
    return n_empty


@jit
def relaxed_meet(
    lo: np.ndarray,
    hi: np.ndarray,
    variables: np.ndarray,
    is_angle: np.ndarray,
    allowance: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    entry_member: np.ndarray,
    entry_slot: np.ndarray,
    out_lo: np.ndarray,
    out_hi: np.ndarray,
    empty: np.ndarray,
    rtol: float,
    changed: np.ndarray,
) -> int:
    """Narrow variables to the q-relaxed intersection of groups of their members' contractions.

    Group i narrows variable ``variables[i]`` with the members
    ``entry_member[starts[i]:ends[i]]`` (their contraction of it in column ``entry_slot``
    of ``out_lo``/``out_hi``), at most ``allowance[i]`` of them outliers. A variable may
    have several groups (all its members, and those of each block of poses): each gives
    an enclosure of the truth, and they are met in turn. ``changed[i]`` is set when group
    i shrank its variable by more than ``rtol``. Returns ``RELAXED_INCONSISTENT`` when
    some variable is left empty (a proof that more members are outliers than the
    allowance), else ``RELAXED_CONSISTENT``.
    """
    reframed = np.zeros(lo.shape[0], dtype=np.bool_)
    for i in range(variables.shape[0]):
        changed[i] = False
        if reframed[variables[i]]:
            # its box was placed anew on the circle: the members' arcs, computed in the old
            # frame, may hold another representative; the next sweep recomputes them
            continue
        start, end = starts[i], ends[i]
        k = end - start
        need = k - allowance[i]
        if need <= 0:
            continue
        v = variables[i]
        lows = np.empty(k)
        highs = np.empty(k)
        for e in range(start, end):
            m = entry_member[e]
            if empty[m]:
                lows[e - start] = np.inf
                highs[e - start] = -np.inf
            else:
                lows[e - start] = out_lo[m, entry_slot[e]]
                highs[e - start] = out_hi[m, entry_slot[e]]
        if is_angle[i] and not hi[v] - lo[v] <= ANGLE_MARGIN:
            found, new_lo, new_hi = circular_meet(lows, highs, need, lo[v], hi[v])
            if found == _EMPTY_ARC:
                return RELAXED_INCONSISTENT
            if found == _NARROWED:
                changed[i] = True
                reframed[v] = True
                lo[v], hi[v] = new_lo, new_hi
            continue
        lows.sort()
        highs.sort()
        new_lo = max(lo[v], lows[need - 1])
        new_hi = min(hi[v], highs[k - need])
        if not new_lo <= new_hi:
            return RELAXED_INCONSISTENT
        changed[i] = shrunk(lo[v], hi[v], new_lo, new_hi, rtol) or (
            (lo[v] == -np.inf and new_lo > -np.inf) or (hi[v] == np.inf and new_hi < np.inf)
        )
        lo[v], hi[v] = new_lo, new_hi
    return RELAXED_CONSISTENT


_KEPT = 0
_NARROWED = 1
_EMPTY_ARC = 2


@jit
def circular_meet(
    lows: np.ndarray, highs: np.ndarray, need: int, old_lo: float, old_hi: float
) -> tuple[int, float, float]:
    """The shortest arc holding every angle in at least ``need`` of the arcs
    ``[lows[j], highs[j]]`` modulo 2 pi (an empty member has ``lows[j] > highs[j]``),
    placed inside ``[old_lo, old_hi]`` (at least 2 pi wide).

    Returns ``(_NARROWED, lo, hi)``, ``(_KEPT, old_lo, old_hi)`` when no arc shorter than
    2 pi fits, or ``(_EMPTY_ARC, ...)`` when no angle lies in ``need`` arcs (a proof).
    """
    k = lows.shape[0]
    n_full = 0
    starts = np.empty(2 * k)
    ends = np.empty(2 * k)
    n = 0
    for j in range(k):
        a, b = lows[j], highs[j]
        if not a <= b:
            continue
        if not (abs(a) < ARC_LIMIT and abs(b) < ARC_LIMIT):
            return _KEPT, old_lo, old_hi
        width = b - a + 2.0 * ARC_SLACK
        if width >= TWO_PI - 4.0 * ARC_SLACK:
            n_full += 1
            continue
        start = (a - ARC_SLACK) - TWO_PI * math.floor((a - ARC_SLACK) / TWO_PI)
        end = start + width
        if end > TWO_PI:  # split at 0
            starts[n], ends[n] = start, TWO_PI
            starts[n + 1], ends[n + 1] = 0.0, end - TWO_PI
            n += 2
        else:
            starts[n], ends[n] = start, end
            n += 1
    left = need - n_full
    if left <= 0:
        return _KEPT, old_lo, old_hi
    # sweep: +1 at a start, -1 after an end (closed arcs), starts first at ties
    positions = np.empty(2 * n)
    steps = np.empty(2 * n, dtype=np.int64)
    for j in range(n):
        positions[2 * j], steps[2 * j] = starts[j], 1
        positions[2 * j + 1], steps[2 * j + 1] = ends[j], -1
    order = _event_order(positions, steps)
    covered_lo = np.empty(n + 1)
    covered_hi = np.empty(n + 1)
    m = 0
    count = 0
    for e in order:
        before = count
        count += steps[e]
        if before < left <= count:
            covered_lo[m] = positions[e]
        elif count < left <= before:
            covered_hi[m] = positions[e]
            m += 1
    if m == 0:
        return _EMPTY_ARC, old_lo, old_hi
    # the largest gap between covered pieces, on the circle; the arc is its complement
    best_gap = -1.0
    arc_lo, arc_hi = 0.0, 0.0
    for j in range(m):
        nxt = covered_lo[(j + 1) % m] + (TWO_PI if j + 1 == m else 0.0)
        gap = nxt - covered_hi[j]
        if gap > best_gap:
            best_gap = gap
            arc_lo = covered_lo[(j + 1) % m]
            arc_hi = covered_hi[j] + (TWO_PI if j + 1 < m else 0.0)
    if m == 1:
        arc_lo, arc_hi = covered_lo[0], covered_hi[0]
        if covered_lo[0] <= 0.0 and covered_hi[0] >= TWO_PI:
            return _KEPT, old_lo, old_hi
    arc_lo -= ARC_SLACK
    arc_hi += ARC_SLACK
    if not arc_hi - arc_lo < TWO_PI - 4.0 * ARC_SLACK:
        return _KEPT, old_lo, old_hi
    # place the arc inside the old box
    if math.isfinite(old_lo):
        shift = math.ceil((old_lo - arc_lo) / TWO_PI)
    elif math.isfinite(old_hi):
        shift = math.floor((old_hi - arc_hi) / TWO_PI)
    else:
        shift = 0.0
    if abs(shift) * TWO_PI > ARC_LIMIT:
        return _KEPT, old_lo, old_hi
    new_lo = arc_lo + TWO_PI * shift - ARC_SLACK
    new_hi = arc_hi + TWO_PI * shift + ARC_SLACK
    if new_lo < old_lo or new_hi > old_hi:
        return _KEPT, old_lo, old_hi
    return _NARROWED, new_lo, new_hi


@jit
def _event_order(positions: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Events by position, starts before ends at the same position (closed arcs)."""
    order = np.argsort(positions, kind="mergesort")
    out = np.empty(positions.shape[0], dtype=np.int64)
    n = 0
    j = 0
    while j < order.shape[0]:
        t = j
        while t < order.shape[0] and positions[order[t]] == positions[order[j]]:
            t += 1
        for e in range(j, t):
            if steps[order[e]] > 0:
                out[n] = order[e]
                n += 1
        for e in range(j, t):
            if steps[order[e]] < 0:
                out[n] = order[e]
                n += 1
        j = t
    return out
