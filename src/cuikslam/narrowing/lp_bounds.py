"""Certified bounds of variables over a linear relaxation: HiGHS proposes, intervals decide.

Each variable is minimised (or maximised) over ``{x in box, row_lo <= A x <= row_hi}`` with
HiGHS, and the bound is then re-derived from the LP's row multipliers ``y`` in interval
arithmetic (Neumaier and Shcherbina's safe bound, :mod:`.safe_bound`): for *any* ``y``,
``c x = (c - A^T y) x + y (A x)`` and each term is bounded over its box. So the LP solver
is never trusted: a wrong, inaccurate or unfinished LP can only weaken a bound.

Every LP has a budget: an iteration limit (a multiple of its size; a dual simplex that
cycles on a degenerate LP otherwise never stops, which is what hung ``lp-split`` on a log
with nanometre odometry) and, when the caller's budget has a wall-clock cap, a time limit
(at most ``LP_TIME_LIMIT``, less when the cap is nearer; without one no LP depends on the
clock, so the boxes do not depend on the machine's load). Each LP spends work in
proportion to its size (:data:`cuikslam.budget.COSTS`). An LP that stops on a
limit still gives the safe bound of whatever multipliers it has; its warm-start basis is
dropped, and an LP that was started from a previous basis and did not reach an optimum is
solved once more from scratch.

The LPs of one call differ only in their cost, so after HiGHS's first optimum the others
are solved by a compiled primal simplex (:mod:`._simplex`) from the last optimum: on these
small LPs HiGHS's fixed cost per call dominates, and the kernel's iterations are cheaper
than HiGHS's (figures in ``docs/benchmarks.md``, "Long logs"). An LP the kernel cannot
finish goes back to HiGHS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import highspy
import numpy as np
from scipy import sparse

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import COSTS, Budget, expired, remaining, spend
from cuikslam.narrowing import _simplex
from cuikslam.narrowing.lp_multipliers import _keep_sparse, _reused, _sparse
from cuikslam.narrowing.safe_bound import (
    safe_bound,
    safe_bounds_of_columns,
    safe_lower_bound,
)

__all__ = [
    "LP_ITERATIONS_PER_SIZE",
    "LP_MIN_ITERATIONS",
    "LP_TIME_LIMIT",
    "LpStatistics",
    "WarmStarts",
    "certified_bounds",
]

LP_TIME_LIMIT = 0.5
"""Seconds one LP may take at most when the caller's budget has a wall-clock cap (a typical
one takes a few milliseconds)."""
LP_SAFETY_TIME = 10.0
"""Seconds one LP may take at most without a deadline: a safety net only. HiGHS's primal
simplex once ran for more than 5 minutes on a 335 x 116 LP of a property test (phase 1,
past its iteration limit) after the compiled simplex had failed; a bound from the duals it
stops with is still safe (:func:`safe_bound`), only weaker."""
LP_ITERATIONS_PER_SIZE = 10
"""Simplex iterations one LP may take, per row and column (typical: about one third)."""
LP_MIN_ITERATIONS = 1000
PRIMAL_SIMPLEX = 4
"""HiGHS's ``simplex_strategy`` for primal simplex. Consecutive LPs differ only in their
cost vector, so the last optimal basis stays primal feasible: primal simplex needs about a
third of the iterations of dual simplex from it (measured on random worlds)."""

REUSE_COLUMN_BASIS = True
"""Without the kernel, each column's LP starts from its optimal basis of the last call."""
SEQUENCE_KERNEL = True
"""Solve a window's LPs with :mod:`._simplex` from HiGHS's first optimum."""
KERNEL_CHUNK = 16
"""LPs per call of the kernel (the deadline is looked at between calls)."""
KERNEL_ITERATIONS = 2000
"""Simplex iterations one LP may take in the kernel before HiGHS takes it over."""
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
    """Optimal LP bases of earlier calls, per column and direction, and the last basis of
    the last sequence (see :func:`certified_bounds`)."""

    minima: dict[int, highspy.HighsBasis] = field(default_factory=dict)
    maxima: dict[int, highspy.HighsBasis] = field(default_factory=dict)
    last: highspy.HighsBasis | None = None
    duals: dict[tuple[int, bool], tuple[int, np.ndarray, np.ndarray]] = field(default_factory=dict)
    """The row multipliers of the last LP of each column and direction (True: minimum), as
    (rows, indices of the nonzero ones, their values): a window keeps one per bound, so
    they are stored small (see ``_sparse``)."""


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


def certified_bounds(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    warm: WarmStarts,
    deadline: Budget | None = None,
    statistics: LpStatistics | None = None,
    upper_columns: list[int] | None = None,
    reuse: bool = False,
) -> tuple[list[float], list[float]]:
    """Certified minima and maxima of the ``columns`` over the polytope.

    With ``SEQUENCE_KERNEL`` (the default) the LPs run in the order given, minima then
    maxima, as one sequence: HiGHS solves the first and :mod:`._simplex` the others from
    the last optimum, so an order in which consecutive optima are close is fastest. Each
    bound is the safe bound of the multipliers found, whoever found them.

    Parameters
    ----------
    csc, row_lo, row_hi, box
        The polytope, as in :func:`.safe_bound.safe_lower_bound`.
    columns : list of int
        Columns to bound.
    warm : WarmStarts
        Optimal bases of earlier calls on the same rows; read and updated.
    deadline : Budget or None
        A :func:`time.perf_counter` value after which no further LP is started (those
        bounds stay infinite) and running LPs stop.
    statistics : LpStatistics or None
        Counts are added here.
    upper_columns : list of int or None
        Columns to bound from above, when not the same as ``columns`` (which are then
        bounded from below only).
    reuse : bool
        Solve no LP: each bound is the safe bound of the multipliers of the column's last
        LP in ``warm`` (over these rows, which may differ from that LP's), ``-inf`` /
        ``inf`` where there is none.

    Returns
    -------
    tuple of list of float
        ``(lower, upper)``, one per column of ``columns`` and ``upper_columns``: ``-inf`` /
        ``inf`` where nothing was certified.
    """
    upper_columns = columns if upper_columns is None else upper_columns
    if reuse:
        return _reused(csc, row_lo, row_hi, box, columns, upper_columns, warm)
    if SEQUENCE_KERNEL:
        lower, upper, stats = _sequence(
            csc, row_lo, row_hi, box, columns, upper_columns, warm, deadline
        )
        if statistics is not None:
            statistics.add(stats)
        return lower, upper
    lower, stats_lo = _bounds(csc, row_lo, row_hi, box, columns, 1.0, warm.minima, deadline)
    upper, stats_hi = _bounds(csc, row_lo, row_hi, box, upper_columns, -1.0, warm.maxima, deadline)
    if statistics is not None:
        statistics.add(stats_lo)
        statistics.add(stats_hi)
    return lower, upper


def _bounds(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    sense: float,
    bases: dict[int, highspy.HighsBasis],
    deadline: Budget | None,
) -> tuple[list[float], LpStatistics]:
    """Certified minima (sense 1) or maxima (sense -1) of the ``columns``, and counts."""
    ensure_round_to_nearest()  # the rounding mode is per thread
    stats = LpStatistics()
    solver = _SOLVER()
    solver.setOptionValue("output_flag", False)
    solver.setOptionValue("presolve", "off")
    solver.setOptionValue("simplex_strategy", PRIMAL_SIMPLEX)
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
    objective = np.zeros(len(box))
    for j in columns:
        if expired(deadline):
            stats.skipped += 1
            out.append(keep)
            continue
        if previous >= 0:
            solver.changeColCost(previous, 0.0)
        solver.changeColCost(j, sense)
        previous = j
        basis = bases.pop(j, None) if REUSE_COLUMN_BASIS else None
        if basis is not None and (len(basis.col_status), len(basis.row_status)) == shape:
            solver.setBasis(basis)
            fresh = False
        status = _run(solver, deadline, stats, size)
        if status != _OPTIMAL and not fresh and not expired(deadline):
            # a warm start (this column's basis, or the last LP's) that went nowhere
            solver.clearSolver()
            stats.retries += 1
            status = _run(solver, deadline, stats, size)
        if status == _OPTIMAL:
            stats.optimal += 1
            bases[j] = solver.getBasis()
        else:
            stats.limit_hits += status in _LIMITS
        objective[j] = sense
        bound = safe_lower_bound(csc, row_lo, row_hi, objective, solver.getSolution().row_dual, box)
        objective[j] = 0.0
        fresh = status != _OPTIMAL
        if fresh:
            solver.clearSolver()  # the next LP starts afresh, not from a stuck state
        out.append(bound if sense > 0 else -bound)
    return out, stats


def _new_solver(csc: sparse.csc_matrix, row_lo, row_hi, box) -> highspy.Highs:
    solver = _SOLVER()
    solver.setOptionValue("output_flag", False)
    solver.setOptionValue("presolve", "off")
    solver.setOptionValue("simplex_strategy", PRIMAL_SIMPLEX)
    size = csc.shape[0] + csc.shape[1]
    solver.setOptionValue(
        "simplex_iteration_limit", max(LP_MIN_ITERATIONS, LP_ITERATIONS_PER_SIZE * size)
    )
    solver.passModel(_model(csc, row_lo, row_hi, box))
    return solver


_STATUS = (
    highspy.HighsBasisStatus.kLower,
    highspy.HighsBasisStatus.kBasic,
    highspy.HighsBasisStatus.kUpper,
)


def _highs_basis(ids: np.ndarray, side: np.ndarray, m: int, n: int) -> highspy.HighsBasis:
    """The HiGHS basis whose nonbasic variables are the active constraints ``ids``."""
    status = np.ones(m + n, dtype=np.int64)
    status[ids] = np.where(side == 1, 2, 0)
    basis = highspy.HighsBasis()
    basis.row_status = [_STATUS[v] for v in status[:m].tolist()]
    basis.col_status = [_STATUS[v] for v in status[m:].tolist()]
    basis.valid = True
    return basis


def _sequence(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    columns: list[int],
    upper_columns: list[int],
    warm: WarmStarts,
    deadline: Budget | None,
) -> tuple[list[float], list[float], LpStatistics]:
    """Certified minima of ``columns`` then maxima of ``upper_columns``, as one sequence:
    HiGHS solves an LP whenever the sequence needs a vertex (the first, or after the
    kernel gives up on one), :func:`._simplex.solve_sequence` solves the others from the
    last optimum. Every bound is a safe bound of the multipliers found."""
    ensure_round_to_nearest()
    stats = LpStatistics()
    m, n = csc.shape
    size = m + n
    order = np.array(list(columns) + list(upper_columns), dtype=np.int64)
    senses = np.concatenate([np.ones(len(columns)), -np.ones(len(upper_columns))])
    bounds = np.full(len(order), -math.inf)
    if len(order) == 0:
        return [], [], stats
    csr = csc.tocsr()
    csr.sort_indices()
    lower = np.concatenate([row_lo, box[:, 0]])
    upper = np.concatenate([row_hi, box[:, 1]])
    box_lo, box_hi = np.ascontiguousarray(box[:, 0]), np.ascontiguousarray(box[:, 1])
    objective = np.zeros(n)
    duals = np.zeros((len(order), m))
    solver = None
    fresh = True  # no basis in the solver: a failed LP is not retried
    costed = 0
    state = None
    q = 0
    while q < len(order):
        if expired(deadline):
            stats.skipped += len(order) - q
            break
        if state is None:
            if solver is None:
                solver = _new_solver(csc, row_lo, row_hi, box)
                if warm.last is not None and len(warm.last.col_status) == n:
                    solver.setBasis(warm.last)
                    fresh = False
            else:
                solver.changeColCost(costed, 0.0)
            costed = int(order[q])
            solver.changeColCost(costed, float(senses[q]))
            status = _run(solver, deadline, stats, size)
            if status != _OPTIMAL and not fresh and not expired(deadline):
                # a warm start that went nowhere: once more from scratch
                solver.clearSolver()
                stats.retries += 1
                status = _run(solver, deadline, stats, size)
            objective[order[q]] = senses[q]
            y = np.asarray(solver.getSolution().row_dual, dtype=np.float64) + 0.0
            if y.shape == (m,) and np.all(np.isfinite(y)):
                bounds[q] = safe_bound(
                    csc.indptr, csc.indices, csc.data, row_lo, row_hi, objective, y, box_lo, box_hi
                )  # fmt: skip
                warm.duals[int(order[q]), senses[q] > 0] = _sparse(y)
            objective[order[q]] = 0.0
            if status == _OPTIMAL:
                stats.optimal += 1
                basis = solver.getBasis()
                state = _simplex.active_set(
                    [int(v) for v in basis.col_status],
                    [int(v) for v in basis.row_status],
                    n,
                )
                if state is not None:
                    inverse = _inverse(state[0], csr, n, deadline)
                    state = None if inverse is None else state
            else:
                stats.limit_hits += status in _LIMITS
                solver.clearSolver()  # the next LP starts afresh, not from a stuck state
            fresh = status != _OPTIMAL
            q += 1
            continue
        ids, side = state
        stop = min(len(order), q + KERNEL_CHUNK)
        code, at, pivots = _simplex.solve_sequence(
            csr.indptr, csr.indices, csr.data, lower, upper, ids, side, inverse, order,
            senses, q, stop, KERNEL_ITERATIONS, duals,
        )  # fmt: skip
        safe_bounds_of_columns(
            csc.indptr, csc.indices, csc.data, row_lo, row_hi, order, senses, duals, q, at,
            box_lo, box_hi, bounds,
        )  # fmt: skip
        _keep_sparse(warm, order, senses, duals, q, at)
        stats.solved += at - q
        stats.optimal += at - q
        spend(deadline, (at - q) * size * COSTS["lp_entry"])
        spend(deadline, (pivots + 1) * (2 * n * n + csr.nnz) * COSTS["lp_flop"])
        q = at
        if code == _simplex.REFACTOR:
            inverse = _inverse(ids, csr, n, deadline)
            state = None if inverse is None else state
        elif code == _simplex.FAILED:
            state = None  # HiGHS takes LP q, from the kernel's last vertex
            if solver is not None:
                solver.setBasis(_highs_basis(ids, side, m, n))
                fresh = False
    if state is not None:
        warm.last = _highs_basis(state[0], state[1], m, n)
    bounds[senses < 0] = -bounds[senses < 0]
    k = len(columns)
    return bounds[:k].tolist(), bounds[k:].tolist(), stats


def _inverse(
    ids: np.ndarray, csr: sparse.csr_matrix, n: int, deadline: Budget | None
) -> np.ndarray | None:
    """The dense kernel's inverse of the active constraints ``ids`` (None when singular),
    its work spent."""
    spend(deadline, 2 * n**3 * COSTS["lp_flop"])
    return _simplex.inverse_of_active(ids, csr.indptr, csr.indices, csr.data, n)


def _run(solver: highspy.Highs, deadline: Budget | None, stats: LpStatistics, size: int) -> object:
    """Run one LP of ``size`` rows and columns within its limits (HiGHS's time limit counts
    the instance's total time), and spend its work.

    Without a wall-clock cap the iteration limit decides, with ``LP_SAFETY_TIME`` as a
    safety net far above any LP that finishes: a bound then does not depend on how busy the
    machine is, and a run gives the same boxes every time."""
    seconds = remaining(deadline)
    if seconds == math.inf:  # the iteration limit decides; the time limit is a safety net
        solver.setOptionValue("time_limit", solver.getRunTime() + LP_SAFETY_TIME)
    else:
        allowed = min(LP_TIME_LIMIT, max(seconds, 1e-3))
        solver.setOptionValue("time_limit", solver.getRunTime() + allowed)
    solver.run()
    stats.solved += 1
    spend(deadline, size * COSTS["lp_entry"])
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
