"""A small primal simplex for a sequence of LPs that differ only in their cost.

The LPs of a window (:mod:`.lp_bounds`) share their rows and column bounds: only the
variable minimised or maximised changes. HiGHS solves the first one; its optimal basis
stays primal feasible for every other cost, so the rest need only primal simplex phase 2.
On these small LPs (a few hundred rows, about a hundred columns) HiGHS's fixed cost per
call dominates (figures in ``docs/benchmarks.md``, "Long logs"); this kernel works on the
dense inverse of the active constraints (one per column: a vertex is where ``n``
constraints hold with equality), and computes each safe bound in the same pass.

Nothing here needs to be exact: the simplex only proposes multipliers, and every bound is
re-derived from them in interval arithmetic (:func:`.safe_bound.safe_bound`). A kernel that
stalls or meets anything it does not handle (an unbounded ray, a tiny pivot) stops and
says where, and the caller goes on with HiGHS.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam._jit import jit

__all__ = ["DONE", "FAILED", "REFACTOR", "active_set", "inverse_of_active", "solve_sequence"]

DONE = -1
"""``solve_sequence`` finished every LP."""
REFACTOR = -2
"""``solve_sequence`` stopped to have its inverse recomputed (``at`` is the next LP)."""
FAILED = -3
"""``solve_sequence`` could not finish the LP ``at`` (unbounded, stalled, tiny pivot)."""

_OPTIMALITY = 1e-9
_PIVOT = 1e-7
_FEASIBILITY = 1e-9
_PIVOTS_PER_FACTOR = 500
"""Rank-one updates of the inverse before it is recomputed from scratch."""


def active_set(
    col_status: np.ndarray, row_status: np.ndarray, n_cols: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The active constraints of a HiGHS basis: ids (rows ``0..m-1``, then the bound of
    column ``j`` as ``m + j``) and sides (0 lower, 1 upper); None if it is not a vertex
    this kernel handles (a free nonbasic variable, or not exactly ``n_cols`` of them)."""
    col_status = np.asarray(col_status, dtype=np.int64)
    row_status = np.asarray(row_status, dtype=np.int64)
    basic, lower, upper = 1, 0, 2
    m = len(row_status)
    ids = np.concatenate(
        [np.flatnonzero(row_status != basic), m + np.flatnonzero(col_status != basic)]
    )
    status = np.concatenate([row_status[row_status != basic], col_status[col_status != basic]])
    if len(ids) != n_cols or np.any((status != lower) & (status != upper)):
        return None
    return ids.astype(np.int64), (status == upper).astype(np.int64)


@jit
def _dense_rows(
    ids: np.ndarray, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, n: int
) -> np.ndarray:
    """The active constraints as a dense square matrix (row k: constraint ``ids[k]``)."""
    m = indptr.shape[0] - 1
    basis = np.zeros((n, n))
    for k in range(ids.shape[0]):
        i = ids[k]
        if i < m:
            for p in range(indptr[i], indptr[i + 1]):
                basis[k, indices[p]] = data[p]
        else:
            basis[k, i - m] = 1.0
    return basis


@jit
def _inverse(matrix: np.ndarray) -> np.ndarray:
    """Gauss-Jordan inverse with partial pivoting; an empty array when singular (on such
    small matrices a threaded BLAS on a loaded machine spends far more on its threads than
    on the work)."""
    n = matrix.shape[0]
    a = matrix.copy()
    inv = np.eye(n)
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(a[r, c]) > abs(a[p, c]):
                p = r
        if abs(a[p, c]) < 1e-12:
            return np.empty((0, 0))
        if p != c:
            for k in range(n):
                a[c, k], a[p, k] = a[p, k], a[c, k]
                inv[c, k], inv[p, k] = inv[p, k], inv[c, k]
        scale = 1.0 / a[c, c]
        for k in range(n):
            a[c, k] *= scale
            inv[c, k] *= scale
        for r in range(n):
            f = a[r, c]
            if r != c and f != 0.0:
                for k in range(n):
                    a[r, k] -= f * a[c, k]
                    inv[r, k] -= f * inv[c, k]
    return inv


def inverse_of_active(
    ids: np.ndarray, csr_indptr: np.ndarray, csr_indices: np.ndarray, csr_data: np.ndarray, n: int
) -> np.ndarray | None:
    """The inverse of the active constraints' dense rows (None when singular)."""
    inv = _inverse(_dense_rows(ids, csr_indptr, csr_indices, csr_data, n))
    return inv if inv.shape[0] == n else None


@jit
def solve_sequence(
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    ids: np.ndarray,
    side: np.ndarray,
    inverse: np.ndarray,
    columns: np.ndarray,
    senses: np.ndarray,
    start: int,
    stop: int,
    max_iterations: int,
    duals: np.ndarray,
) -> tuple[int, int, int]:
    """Solve ``min senses[q] * x[columns[q]]`` for q = start, ..., stop - 1 in turn.

    The constraints are the rows of the CSR matrix (``lower[:m] <= A x <= upper[:m]``),
    then the column bounds (``lower[m+j] <= x_j <= upper[m+j]``). The active set
    (``ids``, ``side``, and ``inverse``, the inverse of their dense rows) is updated in
    place, so each LP starts from the last one's optimum. The row multipliers of LP q are
    written to ``duals[q]`` (rows of an LP that did not finish are left as they are).

    Returns ``(code, at, iterations)``: code DONE, REFACTOR (stopped before LP ``at`` to
    have ``inverse`` recomputed) or FAILED (LP ``at`` did not finish).
    """
    m = indptr.shape[0] - 1
    n = inverse.shape[0]
    total = m + n
    active = np.full(total, -1, dtype=np.int64)
    for k in range(n):
        active[ids[k]] = k
    # x from the active constraints, then every constraint's value
    x = np.zeros(n)
    for k in range(n):
        b = upper[ids[k]] if side[k] == 1 else lower[ids[k]]
        for v in range(n):
            x[v] += inverse[v, k] * b
    value = np.empty(total)
    for i in range(m):
        s = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            s += data[p] * x[indices[p]]
        value[i] = s
    for j in range(n):
        value[m + j] = x[j]
    d = np.empty(n)
    rate = np.empty(total)
    w = np.empty(n)
    pivots = 0
    iterations = 0
    for q in range(start, stop):
        if pivots >= _PIVOTS_PER_FACTOR:
            return REFACTOR, q, iterations
        j = columns[q]
        sense = senses[q]
        stalled = 0
        count = 0
        while True:
            # multipliers: c = sense e_j, lambda = sense * row j of the inverse
            # Dantzig's rule; Bland's (smallest constraint id) after many null steps
            bland = stalled >= 2 * n
            best = -_OPTIMALITY
            enter = -1
            for k in range(n):
                i = ids[k]
                if upper[i] == lower[i]:
                    continue
                lam = sense * inverse[j, k]
                gain = lam if side[k] == 0 else -lam  # objective change per unit step
                if gain >= -_OPTIMALITY:
                    continue
                if bland:
                    if enter < 0 or i < ids[enter]:
                        enter = k
                elif gain < best:
                    best = gain
                    enter = k
            if enter < 0:
                break
            if count >= max_iterations:
                return FAILED, q, iterations
            count += 1
            iterations += 1
            direction = 1.0 if side[enter] == 0 else -1.0
            for v in range(n):
                d[v] = direction * inverse[v, enter]
            # Harris' ratio test over the inactive constraints: the largest step that no
            # constraint overshoots by more than _FEASIBILITY, then of the constraints that
            # block within it, the one with the largest rate (the stablest pivot)
            own = ids[enter]
            limit = upper[own] - lower[own]
            for i in range(total):
                if i < m:
                    r = 0.0
                    for p in range(indptr[i], indptr[i + 1]):
                        r += data[p] * d[indices[p]]
                else:
                    r = d[i - m]
                rate[i] = r
                if active[i] >= 0:
                    continue
                # room / r < limit, written without a division for the many that fail it
                if r > _PIVOT:
                    room = upper[i] + _FEASIBILITY - value[i]
                    if room < limit * r:
                        limit = room / r
                elif r < -_PIVOT:
                    room = lower[i] - _FEASIBILITY - value[i]
                    if room > limit * r:
                        limit = room / r
            step = upper[own] - lower[own]
            leave = -1
            largest = 0.0
            if limit < math.inf:
                for i in range(total):
                    if active[i] >= 0:
                        continue
                    r = rate[i]
                    if r > _PIVOT:
                        room = upper[i] - value[i]
                        if room > limit * r or r <= largest:
                            continue
                    elif r < -_PIVOT:
                        room = lower[i] - value[i]
                        if room < limit * r or -r <= largest:
                            continue
                    else:
                        continue
                    largest = abs(r)
                    leave = i
                    step = max(room / r, 0.0)
            if step == math.inf:
                return FAILED, q, iterations
            stalled = stalled + 1 if step <= _FEASIBILITY else 0
            for v in range(n):
                x[v] += step * d[v]
            for i in range(total):
                value[i] += step * rate[i]
            if leave < 0:
                side[enter] = 1 - side[enter]  # the entering constraint reached its other side
                continue
            # leave enters the active set at position enter: B' = B + e_k (g - g_k)^T
            for v in range(n):
                w[v] = 0.0
            if leave < m:
                for p in range(indptr[leave], indptr[leave + 1]):
                    col = indices[p]
                    for k in range(n):
                        w[k] += data[p] * inverse[col, k]
            else:
                for k in range(n):
                    w[k] = inverse[leave - m, k]
            pivot = w[enter]
            if abs(pivot) < _PIVOT:
                return FAILED, q, iterations
            for v in range(n):
                d[v] = inverse[v, enter] / pivot
            w[enter] -= 1.0
            for v in range(n):
                dv = d[v]
                if dv != 0.0:
                    for k in range(n):
                        inverse[v, k] -= dv * w[k]
            active[own] = -1
            active[leave] = enter
            ids[enter] = leave
            side[enter] = 1 if rate[leave] > 0.0 else 0
            pivots += 1
        for i in range(m):
            duals[q, i] = 0.0
        for k in range(n):
            if ids[k] < m:
                duals[q, ids[k]] = sense * inverse[j, k]
    return DONE, stop, iterations
