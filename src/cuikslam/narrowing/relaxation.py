"""Linear relaxation of a whole kinematic graph: a polytope-hull narrowing operator.

Hull consistency treats each factor alone and forgets that consecutive poses are
correlated (the wrapping effect). This operator keeps the correlations: every factor's
equations are replaced, over the current boxes, by linear inequalities that enclose them
(a first-order expansion at the box centre plus a rigorously bounded remainder, the
mean-value form in interval arithmetic). Each variable is then minimised and maximised
over the resulting polytope with HiGHS.

The LP solver works in floating point, so its optimum is not trusted: each bound is
re-derived from the LP's dual multipliers in interval arithmetic (Neumaier and
Shcherbina's safe bound), which is valid for *any* multipliers. A wrong or inaccurate LP
answer can only make a bound weaker, never unsound.
"""

from __future__ import annotations

import functools
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import highspy
import numpy as np
from scipy import sparse

from cuikslam import interval as ia
from cuikslam._fpu import ensure_round_to_nearest
from cuikslam._jit import jit
from cuikslam.graph.encoding import (
    ANGLE,
    KIND,
    LENGTH,
    OBSERVATION,
    ODOMETRY,
    TA,
    TB,
    XA,
    XB,
    YA,
    YB,
)
from cuikslam.interval._rounding import TWO_PI_HI, TWO_PI_LO, add_down, add_up, mul_down, mul_up

__all__ = ["LinearRelaxation", "relax", "tighten"]

_CORNERS = ((0, 0), (1, 1), (0, 1), (1, 0))
"""Corners (length side, angle side) the one-sided linearisations start from."""


@dataclass
class LinearRelaxation:
    """Rows ``row_lo <= A x <= row_hi`` that every solution in the box satisfies."""

    matrix: sparse.csr_matrix
    row_lo: np.ndarray
    row_hi: np.ndarray


def _point(v: np.ndarray) -> np.ndarray:
    return ia.interval(v, v)


def _expansion(
    coefficient: np.ndarray, box: np.ndarray, centre: np.ndarray, slope_box: np.ndarray
) -> np.ndarray:
    """Enclosure of (slope - coefficient) * (box - centre): one mean-value remainder term."""
    return ia.mul(ia.sub(slope_box, _point(coefficient)), ia.sub(box, _point(centre)))


def _polar_rows(
    length: np.ndarray, angles: list[np.ndarray], use_cos: bool
) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    """Linearise g = length * cos(sum(angles)) (or sin) over the boxes.

    Returns ``(a_length, a_angles, K)`` with g - a_length*length - sum(a_k * angle_k) in K
    for every point of the boxes.
    """
    centre_length = 0.5 * (length[:, 0] + length[:, 1])
    centres = [0.5 * (a[:, 0] + a[:, 1]) for a in angles]
    phi_box = angles[0]
    phi_centre = _point(centres[0])
    for a, c in zip(angles[1:], centres[1:], strict=True):
        phi_box = ia.add(phi_box, a)
        phi_centre = ia.add(phi_centre, _point(c))
    trig, dtrig = (ia.cos, ia.sin) if use_cos else (ia.sin, ia.cos)
    phi_mid = 0.5 * (phi_centre[:, 0] + phi_centre[:, 1])
    # g = L cos(phi): dg/dL = cos(phi), dg/dphi = -L sin(phi); g = L sin(phi): sin, L cos
    c_float = np.cos(phi_mid) if use_cos else np.sin(phi_mid)
    d_float = -np.sin(phi_mid) if use_cos else np.cos(phi_mid)
    sign = -1.0 if use_cos else 1.0
    a_length = c_float
    a_angle = centre_length * d_float
    value_centre = ia.mul(_point(centre_length), trig(phi_centre))
    slope_length = trig(phi_box)
    slope_angle = ia.mul(length, dtrig(phi_box))
    if sign < 0:
        slope_angle = ia.neg(slope_angle)
    constant = ia.sub(value_centre, ia.mul(_point(a_length), _point(centre_length)))
    for c in centres:
        constant = ia.sub(constant, ia.mul(_point(a_angle), _point(c)))
    remainder = _expansion(a_length, length, centre_length, slope_length)
    for a, c in zip(angles, centres, strict=True):
        remainder = ia.add(remainder, _expansion(a_angle, a, c, slope_angle))
    return a_length, [a_angle] * len(angles), ia.add(constant, remainder)


def _corner_rows(
    length: np.ndarray, angles: list[np.ndarray], use_cos: bool, length_side: int, angle_side: int
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """One-sided linear bounds of g = length * cos(sum(angles)) (or sin) from a box corner.

    At the corner c (length at its ``length_side`` bound, every angle at its
    ``angle_side`` bound; 0 = lower, 1 = upper) the sign of each x_j - c_j is known, so
    with interval slopes S the mean-value theorem gives, without remainder,
    g(x) >= g(c) + sum_j S_j.lo (x_j - c_j) where x_j - c_j >= 0 (S_j.hi where <= 0), and
    the mirror upper bound. Returns ``(a_length, a_angle, bounds)`` for the two rows.
    """
    corner_length = length[:, length_side]
    phi_box = angles[0]
    phi_corner = _point(angles[0][:, angle_side])
    for a in angles[1:]:
        phi_box = ia.add(phi_box, a)
        phi_corner = ia.add(phi_corner, _point(a[:, angle_side]))
    trig, dtrig = (ia.cos, ia.sin) if use_cos else (ia.sin, ia.cos)
    value = ia.mul(_point(corner_length), trig(phi_corner))
    slope_length = trig(phi_box)
    slope_angle = ia.mul(length, dtrig(phi_box))
    if use_cos:
        slope_angle = ia.neg(slope_angle)
    out = []
    # lower-bound row: slope.lo for a variable at its lower corner, slope.hi at its upper
    for bound_side in (0, 1):
        a_len = slope_length[:, length_side if bound_side == 0 else 1 - length_side]
        a_ang = slope_angle[:, angle_side if bound_side == 0 else 1 - angle_side]
        constant = ia.sub(value, ia.mul(_point(a_len), _point(corner_length)))
        for a in angles:
            constant = ia.sub(constant, ia.mul(_point(a_ang), _point(a[:, angle_side])))
        bounds = np.full((len(a_len), 2), np.inf)
        bounds[:, 0] = -np.inf
        bounds[:, bound_side] = constant[:, bound_side]
        ok = np.isfinite(a_len) & np.isfinite(a_ang)
        bounds[~ok] = (-np.inf, np.inf)
        out.append((np.where(ok, a_len, 0.0), np.where(ok, a_ang, 0.0), bounds))
    return out


def relax(
    factors: np.ndarray, lo: np.ndarray, hi: np.ndarray, corners: bool = True
) -> LinearRelaxation:
    """The linear relaxation of the odometry and observation factors over the box ``[lo, hi]``.

    Factors touching an unbounded variable are left out (a relaxation may omit rows).
    """
    box = np.stack([lo, hi], axis=-1)
    used = factors[np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION))]
    slots = used[:, 1:]
    finite = np.all(np.isfinite(box[np.maximum(slots, 0)]).all(axis=-1) | (slots < 0), axis=1)
    used = used[finite]
    rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (cols, vals, bounds) per row set
    n = len(used)
    if n:
        odo = used[:, KIND] == ODOMETRY
        angle_vars = [used[:, TA], used[:, ANGLE]]
        # the heading that drives the displacement: tb for odometry, ta + bearing otherwise
        for use_cos, target_a, target_b in ((True, XA, XB), (False, YA, YB)):
            length = box[used[:, LENGTH]]
            ang_odo = [box[used[:, TB]]]
            ang_obs = [box[angle_vars[0]], box[angle_vars[1]]]
            for mask, angles, angle_cols in (
                (odo, ang_odo, [used[:, TB]]),
                (~odo, ang_obs, angle_vars),
            ):
                if not mask.any():
                    continue
                cols = np.column_stack(
                    [used[mask, target_b], used[mask, target_a], used[mask, LENGTH]]
                    + [c[mask] for c in angle_cols]
                )
                boxes = [a[mask] for a in angles]
                a_len, a_ang, k = _polar_rows(length[mask], boxes, use_cos)
                linearisations = [(a_len, a_ang[0], k)]
                if corners:
                    for length_side, angle_side in _CORNERS:
                        linearisations += _corner_rows(
                            length[mask], boxes, use_cos, length_side, angle_side
                        )
                for a_len, a_ang, k in linearisations:
                    vals = np.column_stack(
                        [np.ones(mask.sum()), -np.ones(mask.sum()), -a_len]
                        + [-a_ang] * len(angle_cols)
                    )
                    rows.append((cols, vals, k))
        if odo.any():
            # tb - ta - turn = 2 pi k, when a single k fits the boxes
            o = used[odo]
            diff = ia.sub(ia.sub(box[o[:, TB]], box[o[:, TA]]), box[o[:, ANGLE]])
            k_lo = np.ceil(diff[:, 0] / TWO_PI_HI - 1e-12)
            k_hi = np.floor(diff[:, 1] / TWO_PI_LO + 1e-12)
            single = k_lo == k_hi
            k = k_lo[single]
            shift = np.where(
                k >= 0,
                np.stack([k * TWO_PI_LO, k * TWO_PI_HI], axis=-1).T,
                np.stack([k * TWO_PI_HI, k * TWO_PI_LO], axis=-1).T,
            ).T
            shift = ia.interval(
                np.nextafter(shift[:, 0], -np.inf), np.nextafter(shift[:, 1], np.inf)
            )
            cols = np.column_stack([o[single, TB], o[single, TA], o[single, ANGLE]])
            vals = np.tile([1.0, -1.0, -1.0], (single.sum(), 1))
            rows.append((cols, vals, shift))
    if not rows:
        return LinearRelaxation(sparse.csr_matrix((0, len(lo))), np.zeros(0), np.zeros(0))
    cols = np.concatenate([r[0].ravel() for r in rows])
    vals = np.concatenate([r[1].ravel() for r in rows])
    counts = [r[0].shape[1] for r in rows for _ in range(r[0].shape[0])]
    row_ids = np.repeat(np.arange(len(counts)), counts)
    bounds = np.concatenate([r[2] for r in rows])
    matrix = sparse.csr_matrix((vals, (row_ids, cols)), shape=(len(counts), len(lo)))
    return LinearRelaxation(matrix, bounds[:, 0], bounds[:, 1])


@jit
def _transposed_product_bounds(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Enclosure of A^T y for a CSC matrix A (one outward-rounded dot product per column)."""
    n = indptr.shape[0] - 1
    out_lo = np.zeros(n)
    out_hi = np.zeros(n)
    for j in range(n):
        lo = 0.0
        hi = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            lo = add_down(lo, mul_down(data[k], y[indices[k]]))
            hi = add_up(hi, mul_up(data[k], y[indices[k]]))
        out_lo[j] = lo
        out_hi[j] = hi
    return out_lo, out_hi


@jit
def _sum_down(values: np.ndarray) -> float:
    total = 0.0
    for v in values:
        total = add_down(total, v)
    return total


def _safe_lower_bound(
    relaxation: LinearRelaxation,
    csc: sparse.csc_matrix,
    objective: np.ndarray,
    row_dual: np.ndarray,
    box: np.ndarray,
) -> float:
    """A rigorous lower bound of ``objective @ x`` over {x in box, row_lo <= A x <= row_hi}.

    For any multipliers y: c x = (c - A^T y) x + y (A x), each term bounded over its box.
    """
    y = np.asarray(row_dual, dtype=np.float64)
    at_y = ia.interval(*_transposed_product_bounds(csc.indptr, csc.indices, csc.data, y))
    reduced = ia.sub(_point(objective), at_y)
    terms = ia.mul(reduced, box)
    row_terms = ia.mul(_point(y), ia.interval(relaxation.row_lo, relaxation.row_hi))
    lows = np.concatenate([terms[:, 0], row_terms[:, 0]])
    if np.isnan(lows).any():
        return -math.inf
    return _sum_down(lows)


def tighten(
    factors: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    targets: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Narrow the ``targets`` variables to the hull of the linear relaxation of ``factors``.

    Only the variables of ``factors`` enter the LP (so a window of a long graph stays
    small). Returns new ``(lo, hi, feasible)``; ``feasible`` is False when the relaxation
    is proven empty (then the graph has no solution in the box).
    """
    ensure_round_to_nearest()
    lo, hi = lo.copy(), hi.copy()
    slots = factors[:, 1:]
    used = np.unique(slots[slots >= 0])
    local = np.full(len(lo), -1, dtype=np.int64)
    local[used] = np.arange(len(used))
    local_factors = factors.copy()
    local_factors[:, 1:] = np.where(slots >= 0, local[np.maximum(slots, 0)], -1)
    sub_lo, sub_hi = lo[used], hi[used]
    relaxation = relax(local_factors, sub_lo, sub_hi)
    if relaxation.matrix.shape[0] == 0:
        return lo, hi, True
    box = np.stack([sub_lo, sub_hi], axis=-1)
    csc = relaxation.matrix.tocsc()
    columns = [int(local[v]) for v in targets if local[v] >= 0]
    chosen = [int(v) for v in targets if local[v] >= 0]
    # minima and maxima in two threads, each with its own HiGHS instance
    futures = [
        _pool().submit(_bounds, relaxation, csc, box, sub_lo, sub_hi, columns, sense)
        for sense in (1.0, -1.0)
    ]
    lower, upper = (f.result() for f in futures)
    for v, low, high in zip(chosen, lower, upper, strict=True):
        lo[v] = max(lo[v], low)
        hi[v] = min(hi[v], high)
        if lo[v] > hi[v]:
            return lo, hi, False
    return lo, hi, True


@functools.cache
def _pool() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=2, thread_name_prefix="cuikslam-lp")


def _bounds(
    relaxation: LinearRelaxation,
    csc: sparse.csc_matrix,
    box: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    columns: list[int],
    sense: float,
) -> list[float]:
    """Certified minima (sense 1) or maxima (sense -1) of the ``columns`` over the relaxation."""
    ensure_round_to_nearest()  # the rounding mode is per thread
    solver = _load(relaxation, csc, lo, hi)
    out = []
    previous = -1
    for j in columns:
        if previous >= 0:
            solver.changeColCost(previous, 0.0)
        solver.changeColCost(j, sense)
        previous = j
        solver.run()
        if solver.getModelStatus() != highspy.HighsModelStatus.kOptimal:
            out.append(-math.inf if sense > 0 else math.inf)  # no certificate: keep the box
            continue
        objective = np.zeros(len(lo))
        objective[j] = sense
        bound = _safe_lower_bound(relaxation, csc, objective, solver.getSolution().row_dual, box)
        out.append(bound if sense > 0 else -bound)
    return out


def _load(
    relaxation: LinearRelaxation, csc: sparse.csc_matrix, lo: np.ndarray, hi: np.ndarray
) -> highspy.Highs:
    solver = highspy.Highs()
    solver.setOptionValue("output_flag", False)
    solver.setOptionValue("presolve", "off")
    inf = highspy.kHighsInf
    model = highspy.HighsLp()
    model.num_col_ = len(lo)
    model.num_row_ = csc.shape[0]
    model.col_cost_ = np.zeros(len(lo))
    model.col_lower_ = np.where(np.isfinite(lo), lo, -inf)
    model.col_upper_ = np.where(np.isfinite(hi), hi, inf)
    model.row_lower_ = np.where(np.isfinite(relaxation.row_lo), relaxation.row_lo, -inf)
    model.row_upper_ = np.where(np.isfinite(relaxation.row_hi), relaxation.row_hi, inf)
    model.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    model.a_matrix_.start_ = csc.indptr
    model.a_matrix_.index_ = csc.indices
    model.a_matrix_.value_ = csc.data
    solver.passModel(model)
    return solver
