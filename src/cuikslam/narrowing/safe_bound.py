"""Neumaier and Shcherbina's safe bound: a rigorous bound of a linear objective over a
polytope from *any* row multipliers.

``c x = (c - A^T y) x + y (A x)``, and each term is bounded over its box in outward-rounded
interval arithmetic. The LP solver's multipliers make the bound tight; wrong, inaccurate
or unfinished multipliers can only weaken it (:mod:`.lp_bounds` relies on this).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import sparse

from cuikslam._jit import jit
from cuikslam.interval import _arith
from cuikslam.interval._rounding import add_down, add_up, mul_down, mul_up, sub_down, sub_up

__all__ = ["safe_bound", "safe_bounds_of_columns", "safe_lower_bound"]


@jit
def safe_bound(
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    objective: np.ndarray,
    y: np.ndarray,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
) -> float:
    """The safe bound of :func:`safe_lower_bound` for a CSC matrix, in one pass.

    Column ``j`` contributes ``lower((c_j - [A^T y]_j) * box_j)``, row ``i`` contributes
    ``lower(y_i * [row_lo_i, row_hi_i])``; every operation is rounded outward, and a NaN
    term (none is expected) gives no bound at all.

    A multiplier of the wrong sign for a row with an infinite side (a simplex's round-off,
    1e-13 say) would make that row's term infinite: it is set to 0 first (the bound holds
    for any multipliers, so this is as sound as the rest).
    """
    y = y.copy()
    for i in range(y.shape[0]):
        if (y[i] > 0.0 and row_lo[i] == -math.inf) or (y[i] < 0.0 and row_hi[i] == math.inf):
            y[i] = 0.0
    total = 0.0
    for j in range(indptr.shape[0] - 1):
        at_lo = 0.0
        at_hi = 0.0
        for k in range(indptr[j], indptr[j + 1]):
            at_lo = add_down(at_lo, mul_down(data[k], y[indices[k]]))
            at_hi = add_up(at_hi, mul_up(data[k], y[indices[k]]))
        term, _ = _arith.mul(
            sub_down(objective[j], at_hi), sub_up(objective[j], at_lo), box_lo[j], box_hi[j]
        )
        if math.isnan(term):
            return -math.inf
        total = add_down(total, term)
    for i in range(y.shape[0]):
        term, _ = _arith.mul(y[i], y[i], row_lo[i], row_hi[i])
        if math.isnan(term):
            return -math.inf
        total = add_down(total, term)
    if math.isnan(total):
        return -math.inf
    return total


@jit
def safe_bounds_of_columns(
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    columns: np.ndarray,
    senses: np.ndarray,
    duals: np.ndarray,
    start: int,
    stop: int,
    box_lo: np.ndarray,
    box_hi: np.ndarray,
    out: np.ndarray,
) -> None:
    """For ``r`` in ``start..stop-1``, ``out[r]`` = :func:`safe_bound` of the objective
    ``senses[r]`` times column ``columns[r]`` with the multipliers ``duals[r]`` (one
    compiled call for a run of LPs instead of one call each)."""
    objective = np.zeros(indptr.shape[0] - 1)
    for r in range(start, stop):
        objective[columns[r]] = senses[r]
        out[r] = safe_bound(
            indptr, indices, data, row_lo, row_hi, objective, duals[r], box_lo, box_hi
        )
        objective[columns[r]] = 0.0


def safe_lower_bound(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    objective: np.ndarray,
    multipliers: np.ndarray,
    box: np.ndarray,
) -> float:
    """A rigorous lower bound of ``objective @ x`` over {x in box, row_lo <= A x <= row_hi}.

    Valid for *any* multipliers ``y`` (the LP's row duals make it tight): ``c x =
    (c - A^T y) x + y (A x)``, each term bounded over its box in outward-rounded interval
    arithmetic.

    Parameters
    ----------
    csc : scipy.sparse.csc_matrix
        The constraint matrix A (rows, columns).
    row_lo, row_hi : numpy.ndarray
        Row bounds (infinite where a side is free).
    objective : numpy.ndarray
        The cost vector c (one entry per column).
    multipliers : numpy.ndarray
        One multiplier per row, of any sign and size.
    box : numpy.ndarray
        Column bounds, shape (columns, 2) (infinite where free).

    Returns
    -------
    float
        A lower bound (``-inf`` when the multipliers are not finite or give nothing).
    """
    y = np.asarray(multipliers, dtype=np.float64)
    if y.shape != (csc.shape[0],) or not np.all(np.isfinite(y)):
        return -math.inf
    y = y + 0.0  # -0.0 -> 0.0
    box = np.asarray(box, dtype=np.float64)
    return safe_bound(
        csc.indptr, csc.indices, csc.data, np.asarray(row_lo, dtype=np.float64),
        np.asarray(row_hi, dtype=np.float64), np.asarray(objective, dtype=np.float64), y,
        np.ascontiguousarray(box[:, 0]), np.ascontiguousarray(box[:, 1]),
    )  # fmt: skip
