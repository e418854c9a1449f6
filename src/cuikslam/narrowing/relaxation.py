"""Linear relaxation of a whole kinematic graph: the rows of the polytope-hull operator.

Hull consistency treats each factor alone and forgets that consecutive poses are
correlated (the wrapping effect). This operator keeps the correlations: every factor's
equations are replaced, over the current boxes, by linear inequalities that enclose them,
and each variable is then minimised and maximised over the resulting polytope with HiGHS.

A displacement ``d = length * cos(phi)`` is split at an auxiliary column ``t = cos(phi)``:
``t`` is held between tangent and secant lines in ``phi`` (their offsets bounded by a
second-order Taylor form in interval arithmetic), ``d`` by the McCormick envelope of the
product ``length * t``, and the cos and sin columns of one heading by lines through the
arc they lie on. Each piece is nearly exact on small boxes, which keeps the polytope
within a few per cent of the solution set on the seed's experiment.

The polytope's rows are built here; :mod:`.polytope` bounds the variables over them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.encoding import (
    ANGLE,
    KIND,
    LENGTH,
    OBSERVATION,
    ODOMETRY,
    RELATIVE,
    ROTATION,
    TA,
    TB,
    XA,
    XB,
    YA,
    YB,
)
from cuikslam.interval import ops as _ops
from cuikslam.interval._periodic import _shift_bounds, periodic_meet_k

END_TANGENTS_ABOVE = 0.3
"""Tangents at the ends of an angle's interval are kept when it is wider than this (rad)."""

__all__ = ["LinearRelaxation", "relax"]


class _Unguarded:
    """The interval operations of :mod:`cuikslam.interval.ops` as the bare NumPy ufuncs
    that numba compiled, without the check of the rounding mode and numba's argument
    handling (a few hundred calls per relaxation): :func:`relax` checks the mode once."""

    def __getattr__(self, name: str) -> Callable:
        op = getattr(_ops, name)
        op = getattr(op, "__wrapped__", op)
        op = getattr(op, "ufunc", op)  # numba's compiled NumPy ufunc itself
        setattr(self, name, op)
        return op


ia = _Unguarded()


@dataclass
class LinearRelaxation:
    """Rows ``row_lo <= A x <= row_hi`` that every solution in the box satisfies."""

    matrix: sparse.csr_matrix
    row_lo: np.ndarray
    row_hi: np.ndarray
    col_lo: np.ndarray
    """Bounds of every column: the box, then the auxiliary trigonometric columns."""
    col_hi: np.ndarray
    aux_angles: np.ndarray
    """Per auxiliary column, the one or two angle columns whose sum it is the cos/sin of."""
    aux_is_cos: np.ndarray

    def lift(self, values: np.ndarray) -> np.ndarray:
        """A point of the box, extended with its auxiliary values (cos/sin of angle sums)."""
        phi = values[self.aux_angles[:, 0]] + np.where(
            self.aux_angles[:, 1] >= 0, values[self.aux_angles[:, 1]], 0.0
        )
        return np.concatenate([values, np.where(self.aux_is_cos, np.cos(phi), np.sin(phi))])


def _point(v: np.ndarray) -> np.ndarray:
    """The intervals ``[v, v]`` (one allocation: ``np.stack`` costs a few times more on
    these small arrays, and a window's relaxation makes a few hundred)."""
    out = np.empty((*np.shape(v), 2))
    out[..., 0] = v
    out[..., 1] = v
    return out


def _trig_range_rows(phi: np.ndarray, use_cos: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    """Ranged rows ``lo <= g(phi) - m * phi <= hi`` for g = cos (or sin) over the boxes ``phi``.

    One row per slope m: the tangents at both ends and the middle, and the secant. The
    range of h = g - m*phi is enclosed by a second-order Taylor form at the middle, and
    on the side where h is concave (convex) by its end values, which are then exact.
    Returns ``(m, bounds)`` per slope.
    """
    a, b = phi[:, 0], phi[:, 1]
    middle = 0.5 * (a + b)
    radius = np.nextafter(np.maximum(middle - a, b - middle), np.inf)
    g, dg = (ia.cos, ia.sin) if use_cos else (ia.sin, ia.cos)
    # g' = -sin for cos and cos for sin; g'' = -g
    second = ia.neg(g(phi))
    concave, convex = second[:, 1] <= 0.0, second[:, 0] >= 0.0
    slope_at = (lambda x: -np.sin(x)) if use_cos else np.cos
    with np.errstate(invalid="ignore", divide="ignore"):
        secant = np.where(b > a, (g(_point(b))[:, 0] - g(_point(a))[:, 0]) / (b - a), 0.0)
    secant = np.where(np.isfinite(secant), secant, slope_at(middle))
    step = ia.interval(-radius, radius)

    def h(x: np.ndarray, m: np.ndarray) -> np.ndarray:
        return ia.sub(g(_point(x)), ia.mul(_point(m), _point(x)))

    derivative = dg(_point(middle))
    if use_cos:
        derivative = ia.neg(derivative)
    curvature = ia.mul(second, ia.mul(_point(np.full_like(a, 0.5)), ia.sqr(step)))
    out = []
    narrow = (b - a) <= END_TANGENTS_ABOVE
    for m, at_end in (
        (slope_at(a), True),
        (slope_at(middle), False),
        (slope_at(b), True),
        (secant, False),
    ):
        taylor = ia.add(
            ia.add(h(middle, m), ia.mul(ia.sub(derivative, _point(m)), step)), curvature
        )
        ends_a, ends_b = h(a, m), h(b, m)
        lower = np.where(
            concave, np.maximum(taylor[:, 0], np.minimum(ends_a[:, 0], ends_b[:, 0])), taylor[:, 0]
        )
        upper = np.where(
            convex, np.minimum(taylor[:, 1], np.maximum(ends_a[:, 1], ends_b[:, 1])), taylor[:, 1]
        )
        if at_end:  # on a narrow arc the middle tangent and the secant hold it as well
            lower = np.where(narrow, -np.inf, lower)
            upper = np.where(narrow, np.inf, upper)
        out.append((m, np.stack([lower, upper], axis=-1)))
    return out


def _circle_rows(
    phi: np.ndarray, cols: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Rows tying ``c = cos(phi)`` and ``s = sin(phi)`` (columns ``cols``) through the arc.

    For a direction p, ``cos(p) c + sin(p) s = cos(phi - p)``, which lies between
    cos(r) (r the farthest distance from p to the box, when r <= pi) and 1. The
    coefficients are rounded, which moves the value by at most 2 ulp (|c|, |s| <= 1).
    """
    a, b = phi[:, 0], phi[:, 1]
    middle = 0.5 * (a + b)
    out = []
    slack = 4.0 * np.finfo(float).eps
    for p, r in (
        (middle, np.nextafter(np.maximum(middle - a, b - middle), np.inf)),
        (a, np.nextafter(b - a, np.inf)),
        (b, np.nextafter(b - a, np.inf)),
    ):
        with np.errstate(invalid="ignore"):
            lower = np.where(r <= 3.0, ia.cos(_point(np.minimum(r, 3.0)))[:, 0] - slack, -np.inf)
        bounds = np.stack([lower, np.full_like(lower, 1.0 + slack)], axis=-1)
        out.append((cols, np.column_stack([np.cos(p), np.sin(p)]), bounds))
    return out


def _product_rows(
    length: np.ndarray, trig: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """McCormick rows for d = length * t over the boxes: ``d - a_len*length - a_t*t`` bounds.

    Returns ``(a_len, a_t, bounds)`` for the four rows (two lower, two upper bounds).
    """
    out = []
    for length_side, trig_side, bound_side in ((0, 0, 0), (1, 1, 0), (1, 0, 1), (0, 1, 1)):
        a_len = trig[:, trig_side]
        a_t = length[:, length_side]
        constant = ia.neg(ia.mul(_point(a_t), _point(a_len)))
        bounds = np.full((len(a_len), 2), np.inf)
        bounds[:, 0] = -np.inf
        bounds[:, bound_side] = constant[:, bound_side]
        out.append((a_len, a_t, bounds))
    return out


@np.errstate(over="ignore", invalid="ignore")  # huge boxes: see the end of relax
def relax(factors: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> LinearRelaxation:
    """The linear relaxation of the odometry and observation factors over the box ``[lo, hi]``.

    Columns are the box's variables, then one auxiliary column per factor for each of
    cos(phi) and sin(phi) (see :meth:`LinearRelaxation.lift`). Factors touching an
    unbounded variable are left out (a relaxation may omit rows).
    """
    ensure_round_to_nearest()
    n = len(lo)
    box = np.stack([lo, hi], axis=-1)
    used = factors[np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION, RELATIVE, ROTATION))]
    slots = used[:, 1:]
    finite = np.all(np.isfinite(box[np.maximum(slots, 0)]).all(axis=-1) | (slots < 0), axis=1)
    used = used[finite]
    rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (cols, vals, bounds) per row set
    aux_boxes: list[np.ndarray] = []
    aux_angles: list[np.ndarray] = []
    aux_cos: list[np.ndarray] = []
    odo = used[:, KIND] == ODOMETRY
    obs = used[:, KIND] == OBSERVATION
    # the heading that drives the displacement: tb for odometry, ta + bearing otherwise
    for mask, angle_cols in ((odo, [used[:, TB]]), (obs, [used[:, TA], used[:, ANGLE]])):
        if not mask.any():
            continue
        count = int(mask.sum())
        angle_cols = [c[mask] for c in angle_cols]
        angles = [box[c] for c in angle_cols]
        phi = angles[0] if len(angles) == 1 else ia.add(angles[0], angles[1])
        lengths = used[mask, LENGTH]
        length = box[lengths]
        ones = np.ones(count)
        for use_cos, target_a, target_b in ((True, XA, XB), (False, YA, YB)):
            trig = ia.cos(phi) if use_cos else ia.sin(phi)
            aux = n + sum(len(a) for a in aux_boxes) + np.arange(count)
            aux_boxes.append(trig)
            aux_angles.append(
                np.column_stack(angle_cols + [np.full(count, -1)] * (2 - len(angle_cols)))
            )
            aux_cos.append(np.full(count, use_cos))
            trig_cols = np.column_stack([aux, *angle_cols])
            for m, k in _trig_range_rows(phi, use_cos):
                rows.append((trig_cols, np.column_stack([ones] + [-m] * len(angle_cols)), k))
            product_cols = np.column_stack(
                [used[mask, target_b], used[mask, target_a], lengths, aux]
            )
            for a_len, a_t, k in _product_rows(length, trig):
                rows.append((product_cols, np.column_stack([ones, -ones, -a_len, -a_t]), k))
        # the cos column of this group precedes its sin column by ``count``
        rows.extend(_circle_rows(phi, np.column_stack([aux - count, aux])))
    turns = np.isin(used[:, KIND], (ODOMETRY, ROTATION))
    if turns.any():
        rows.extend(_turn_rows(used[turns], box))
    relative = used[used[:, KIND] == RELATIVE]
    if len(relative):
        # cos and sin of ta as auxiliary columns, then b - a = R(ta) (u, v) through them
        phi = box[relative[:, TA]]
        count = len(relative)
        aux_c = n + sum(len(a) for a in aux_boxes) + np.arange(count)
        aux_s = aux_c + count
        trig = (ia.cos(phi), ia.sin(phi))
        for use_cos, aux, trig_box in ((True, aux_c, trig[0]), (False, aux_s, trig[1])):
            aux_boxes.append(trig_box)
            aux_angles.append(np.column_stack([relative[:, TA], np.full(count, -1)]))
            aux_cos.append(np.full(count, use_cos))
            for m, k in _trig_range_rows(phi, use_cos):
                rows.append(
                    (
                        np.column_stack([aux, relative[:, TA]]),
                        np.column_stack([np.ones(count), -m]),
                        k,
                    )
                )
        rows.extend(_circle_rows(phi, np.column_stack([aux_c, aux_s])))
        rows.extend(_rotation_rows(relative, box, trig, aux_c, aux_s))
    aux_box = np.concatenate(aux_boxes) if aux_boxes else np.zeros((0, 2))
    width = n + len(aux_box)
    col_lo = np.concatenate([lo, aux_box[:, 0]])
    col_hi = np.concatenate([hi, aux_box[:, 1]])
    aux_angle_cols = np.concatenate(aux_angles) if aux_angles else np.zeros((0, 2), np.int64)
    aux_is_cos = np.concatenate(aux_cos) if aux_cos else np.zeros(0, bool)
    if not rows:
        matrix = sparse.csr_matrix((0, width))
        return LinearRelaxation(
            matrix, np.zeros(0), np.zeros(0), col_lo, col_hi, aux_angle_cols, aux_is_cos
        )
    cols = np.concatenate([r[0].ravel() for r in rows])
    vals = np.concatenate([r[1].ravel() for r in rows])
    counts = np.concatenate([np.full(r[0].shape[0], r[0].shape[1]) for r in rows])
    row_ids = np.repeat(np.arange(len(counts)), counts)
    bounds = np.concatenate([r[2] for r in rows])
    # huge boxes can overflow a Taylor form to inf - inf: a NaN side is dropped, and so is
    # a row with a coefficient that is not finite (a relaxation may omit rows)
    bad = np.zeros(len(counts), dtype=bool)
    bad[row_ids[~np.isfinite(vals)]] = True
    vals = np.where(bad[row_ids], 0.0, vals)
    bounds[:, 0] = np.where(np.isnan(bounds[:, 0]) | bad, -np.inf, bounds[:, 0])
    bounds[:, 1] = np.where(np.isnan(bounds[:, 1]) | bad, np.inf, bounds[:, 1])
    # rows free on both sides constrain nothing: left out of the matrix
    useful = np.isfinite(bounds).any(axis=1)
    keep = useful[row_ids]
    renumber = np.cumsum(useful) - 1
    matrix = sparse.csr_matrix(
        (vals[keep], (renumber[row_ids[keep]], cols[keep])), shape=(int(useful.sum()), width)
    )
    return LinearRelaxation(
        matrix, bounds[useful, 0], bounds[useful, 1], col_lo, col_hi, aux_angle_cols, aux_is_cos
    )


def _rotation_rows(
    relative: np.ndarray,
    box: np.ndarray,
    trig: tuple[np.ndarray, np.ndarray],
    aux_c: np.ndarray,
    aux_s: np.ndarray,
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Rows for ``xb - xa = u c - v s`` and ``yb - ya = u s + v c`` (c, s = cos, sin ta).

    Each product has a McCormick envelope (:func:`_product_rows`: two lower and two upper
    planes); a sum or difference of two products is bounded by every pair of planes, so
    no column is needed for the products themselves.
    """
    u, v = box[relative[:, ANGLE]], box[relative[:, LENGTH]]
    c_box, s_box = trig
    xa, ya, xb, yb = (relative[:, k] for k in (XA, YA, XB, YB))
    uc, vs = _product_rows(u, c_box), _product_rows(v, s_box)
    us, vc = _product_rows(u, s_box), _product_rows(v, c_box)
    ucol, vcol = relative[:, ANGLE], relative[:, LENGTH]
    out = []
    lower, upper = (0, 1), (2, 3)  # the planes of _product_rows below and above a product
    # x: D = P1 - P2, P1 = u c, P2 = v s: D >= low(P1) - up(P2) and D <= up(P1) - low(P2)
    # y: D = P3 + P4, P3 = u s, P4 = v c: D >= low(P3) + low(P4) and D <= up(P3) + up(P4)
    for b, a, first, second, sign, cols in (
        (xb, xa, uc, vs, -1.0, (ucol, aux_c, vcol, aux_s)),
        (yb, ya, us, vc, 1.0, (ucol, aux_s, vcol, aux_c)),
    ):
        for side in (0, 1):
            mine = lower if side == 0 else upper
            theirs = mine if sign > 0 else (upper if side == 0 else lower)
            for i in mine:
                a1, t1, k1 = first[i]
                for j in theirs:
                    a2, t2, k2 = second[j]
                    constant = (ia.add if sign > 0 else ia.sub)(
                        _point(k1[:, side]), _point(k2[:, 1 - side if sign < 0 else side])
                    )
                    bounds = np.full((len(relative), 2), np.inf)
                    bounds[:, 0] = -np.inf
                    bounds[:, side] = constant[:, side]
                    vals = np.column_stack(
                        [np.ones(len(b)), -np.ones(len(b)), -a1, -t1, -sign * a2, -sign * t2]
                    )
                    out.append((np.column_stack([b, a, *cols]), vals, bounds))
    return out


def _turn_rows(
    odometry: np.ndarray, box: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``tb - ta - turn = 2 pi k``, for the odometry factors where a single k fits the boxes.

    The k that fit are found by the interval kernel's :func:`periodic_meet_k` (the copies
    ``2 pi k`` of 0 that meet ``tb - ta - turn``), and ``2 pi k`` is enclosed by its
    outward-rounded ``_shift_bounds``.
    """
    diff = ia.sub(ia.sub(box[odometry[:, TB]], box[odometry[:, TA]]), box[odometry[:, ANGLE]])
    single = np.zeros(len(odometry), dtype=bool)
    shift = np.empty((len(odometry), 2))
    for f, (lo, hi) in enumerate(diff.tolist()):
        _, _, k_first, k_last = periodic_meet_k(lo, hi, 0.0, 0.0)
        if k_first == k_last and np.isfinite(k_first):
            single[f] = True
            s_lo, s_hi = _shift_bounds(k_first)
            # one more step out: an exact world's truth meets the relation only to within
            # its own precision (1e-391 from 0 at k = 0)
            shift[f] = (np.nextafter(s_lo, -np.inf), np.nextafter(s_hi, np.inf))
    o = odometry[single]
    cols = np.column_stack([o[:, TB], o[:, TA], o[:, ANGLE]])
    vals = np.tile([1.0, -1.0, -1.0], (single.sum(), 1))
    return [(cols, vals, shift[single])]
