"""Certified bounds of variables over a linear relaxation: HiGHS proposes, intervals decide.

Each variable is minimised (or maximised) over ``{x in box, row_lo <= A x <= row_hi}`` with
HiGHS, and the bound is then re-derived from the LP's row multipliers ``y`` in interval
arithmetic (Neumaier and Shcherbina's safe bound, :func:`safe_lower_bound`): for *any* ``y``,
``c x = (c - A^T y) x + y (A x)`` and each term is bounded over its box. So the LP solver
is never trusted: a wrong, inaccurate or unfinished LP can only weaken a bound.

Every LP has a budget: an iteration limit (a multiple of its size; a dual simplex that
cycles on a degenerate LP otherwise never stops, which is what hung ``lp-split`` on a log
with nanometre odometry) and a time limit (at most ``LP_TIME_LIMIT``, less when the
caller's deadline is nearer). An LP that stops on a limit still gives the safe bound of
whatever multipliers it has; its warm-start basis is dropped, and an LP that was started
from a previous basis and did not reach an optimum is solved once more from scratch.
"""

from __future__ import annotations

import functools
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, fields

import highspy
import numpy as np
from scipy import sparse

from cuikslam import interval as ia
from cuikslam._fpu import ensure_round_to_nearest
from cuikslam._jit import jit
from cuikslam.budget import expired, remaining
from cuikslam.interval._rounding import add_down, add_up, mul_down, mul_up

__all__ = [
    "LP_ITERATIONS_PER_SIZE",
    "LP_MIN_ITERATIONS",
    "LP_TIME_LIMIT",
    "LpStatistics",
    "WarmStarts",
    "certified_bounds",
    "safe_lower_bound",
]

LP_TIME_LIMIT = 0.5
"""Seconds one LP may take at most (a typical one takes a few milliseconds)."""
LP_ITERATIONS_PER_SIZE = 10
"""Simplex iterations one LP may take, per row and column (typical: about one third)."""
LP_MIN_ITERATIONS = 1000

_SOLVER = getattr(getattr(highspy, "_core", None), "_Highs", highspy.Highs)
"""The HiGHS class: the bare binding when there is one (the ``highspy.Highs`` wrapper
installs a logging callback that prints a banner on stdout the first time, even when
the output is then switched off), else the wrapper."""
_OPTIMAL = highspy.HighsModelStatus.kOptimal
_LIMITS = (
    highspy.HighsModelStatus.kIterationLimit,
    highspy.HighsModelStatus.kTimeLimit,
)


@dataclass
class WarmStarts:
    """Optimal LP bases of earlier calls, per column and direction."""

    minima: dict[int, highspy.HighsBasis] = field(default_factory=dict)
    maxima: dict[int, highspy.HighsBasis] = field(default_factory=dict)


@dataclass
class LpStatistics:
    """What the LPs did (added up over calls)."""

    solved: int = 0
    """LPs run (a cold retry counts again)."""
    optimal: int = 0
    """LPs that ended optimal (their bound is usually the tightest)."""
    limit_hits: int = 0
    """LPs stopped by their iteration or time limit (their bound is still safe)."""
    retries: int = 0
    """Warm-started LPs that did not reach an optimum, solved again from scratch."""
    skipped: int = 0
    """Bounds not computed because the deadline had passed (the box is kept)."""

    def add(self, other: LpStatistics) -> None:
        """Add ``other``'s counts to these."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


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
    at_y = ia.interval(*_transposed_product_bounds(csc.indptr, csc.indices, csc.data, y))
    reduced = ia.sub(ia.interval(objective, objective), at_y)
    terms = ia.mul(reduced, box)
    row_terms = ia.mul(ia.interval(y, y), ia.interval(row_lo, row_hi))
    lows = np.concatenate([terms[:, 0], row_terms[:, 0]])
    if np.isnan(lows).any():
        return -math.inf
    return _sum_down(lows)


def certified_bounds(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    warm: WarmStarts,
    deadline: float | None = None,
    statistics: LpStatistics | None = None,
) -> tuple[list[float], list[float]]:
    """Certified minima and maxima of the ``columns`` over the polytope (two threads).

    Parameters
    ----------
    csc, row_lo, row_hi, box
        The polytope, as in :func:`safe_lower_bound`.
    columns : list of int
        Columns to bound.
    warm : WarmStarts
        Optimal bases of earlier calls on the same rows; read and updated.
    deadline : float or None
        A :func:`time.perf_counter` value after which no further LP is started (those
        bounds stay infinite) and running LPs stop.
    statistics : LpStatistics or None
        Counts are added here.

    Returns
    -------
    tuple of list of float
        ``(lower, upper)``, one per column: ``-inf`` / ``inf`` where nothing was certified.
    """
    futures = [
        _pool().submit(_bounds, csc, row_lo, row_hi, box, columns, sense, bases, deadline)
        for sense, bases in ((1.0, warm.minima), (-1.0, warm.maxima))
    ]
    (lower, stats_lo), (upper, stats_hi) = (f.result() for f in futures)
    if statistics is not None:
        statistics.add(stats_lo)
        statistics.add(stats_hi)
    return lower, upper


@functools.cache
def _pool() -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=2, thread_name_prefix="cuikslam-lp")


def _bounds(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    sense: float,
    bases: dict[int, highspy.HighsBasis],
    deadline: float | None,
) -> tuple[list[float], LpStatistics]:
    """Certified minima (sense 1) or maxima (sense -1) of the ``columns``, and counts."""
    ensure_round_to_nearest()  # the rounding mode is per thread
    stats = LpStatistics()
    solver = _SOLVER()
    solver.setOptionValue("output_flag", False)
    solver.setOptionValue("presolve", "off")
    size = csc.shape[0] + csc.shape[1]
    solver.setOptionValue(
        "simplex_iteration_limit", max(LP_MIN_ITERATIONS, LP_ITERATIONS_PER_SIZE * size)
    )
    solver.passModel(_model(csc, row_lo, row_hi, box))
    fresh = True  # no basis in the solver: a failed LP is not retried
    shape = (csc.shape[1], csc.shape[0])
    keep = -math.inf if sense > 0 else math.inf
    out = []
    previous = -1
    for j in columns:
        if expired(deadline):
            stats.skipped += 1
            out.append(keep)
            continue
        if previous >= 0:
            solver.changeColCost(previous, 0.0)
        solver.changeColCost(j, sense)
        previous = j
        basis = bases.pop(j, None)
        if basis is not None and (len(basis.col_status), len(basis.row_status)) == shape:
            solver.setBasis(basis)
            fresh = False
        status = _run(solver, deadline, stats)
        if status != _OPTIMAL and not fresh and not expired(deadline):
            # a warm start (this column's basis, or the last LP's) that went nowhere
            solver.clearSolver()
            stats.retries += 1
            status = _run(solver, deadline, stats)
        if status == _OPTIMAL:
            stats.optimal += 1
            bases[j] = solver.getBasis()
        else:
            stats.limit_hits += status in _LIMITS
        objective = np.zeros(len(box))
        objective[j] = sense
        bound = safe_lower_bound(csc, row_lo, row_hi, objective, solver.getSolution().row_dual, box)
        fresh = status != _OPTIMAL
        if fresh:
            solver.clearSolver()  # the next LP starts afresh, not from a stuck state
        out.append(bound if sense > 0 else -bound)
    return out, stats


def _run(solver: highspy.Highs, deadline: float | None, stats: LpStatistics) -> object:
    """Run one LP within its limits (HiGHS's time limit counts the instance's total time)."""
    allowed = min(LP_TIME_LIMIT, max(remaining(deadline), 1e-3))
    solver.setOptionValue("time_limit", solver.getRunTime() + allowed)
    solver.run()
    stats.solved += 1
    return solver.getModelStatus()


def _model(
    csc: sparse.csc_matrix, row_lo: np.ndarray, row_hi: np.ndarray, box: np.ndarray
) -> highspy.HighsLp:
    inf = highspy.kHighsInf
    lo, hi = box[:, 0], box[:, 1]
    model = highspy.HighsLp()
    model.num_col_ = len(lo)
    model.num_row_ = csc.shape[0]
    model.col_cost_ = np.zeros(len(lo))
    model.col_lower_ = np.where(np.isfinite(lo), lo, -inf)
    model.col_upper_ = np.where(np.isfinite(hi), hi, inf)
    model.row_lower_ = np.where(np.isfinite(row_lo), row_lo, -inf)
    model.row_upper_ = np.where(np.isfinite(row_hi), row_hi, inf)
    model.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    model.a_matrix_.start_ = csc.indptr
    model.a_matrix_.index_ = csc.indices
    model.a_matrix_.value_ = csc.data
    return model
