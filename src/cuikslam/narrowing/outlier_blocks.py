"""Branching on which observations of a block of poses are the outliers.

With a bound per block (at most p outliers among the k observations of a block of poses,
:class:`~cuikslam.narrowing.outliers.OutlierScope`), the truth's outliers in the block lie
in some set S of exactly p of them (when k > p). For every such S, the block's other
k - p observations are ordinary constraints: narrowing with them is sound for that S, and
an empty result proves S is not a superset of the outliers. The hull of the boxes of the
surviving sets holds the truth, and is much tighter than the q-relaxed intersection of each
variable on its own when k is small (a pose seen twice gains nothing from the relaxed rule
under "at most 1", but everything from "one of these two is right").

An observation in every surviving set is an outlier (proof: if it were not, the truth's
outliers plus p - 1 others without it would be a surviving set). The sets are enumerated
only while there are at most ``MAX_SETS`` of them in a block and ``MAX_TOTAL`` in a pass.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import Budget, expired
from cuikslam.graph.encoding import KIND, NO_FACTOR, OBSERVATION
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing._propagate import INCONSISTENT, propagate_buffered
from cuikslam.narrowing.propagation import Arrays, Status

__all__ = ["MAX_SETS", "MAX_TOTAL", "BlockBranching", "branch_on_blocks"]

MAX_SETS = 300
"""Sets of outliers enumerated in one block at most (C(k, p)); larger blocks are skipped."""
MAX_TOTAL = 20_000
"""Sets enumerated in one pass over every block at most."""


class BlockBranching:
    """What :func:`branch_on_blocks` did: blocks branched and skipped, sets tried, proven
    outliers."""

    def __init__(self) -> None:
        self.blocks = 0
        self.skipped = 0
        """Blocks left to the relaxed rule alone: too many sets, or the limits reached."""
        self.sets = 0
        self.proven: list[int] = []
        self.applications = 0


def branch_on_blocks(
    hard: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    members: np.ndarray,
    block: np.ndarray,
    allowance: np.ndarray,
    rtol: float,
    max_rounds: int,
    deadline: Budget | None = None,
    report: BlockBranching | None = None,
) -> Status:
    """Narrow ``lo``/``hi`` in place to the hull, block by block, over the sets of outliers.

    Parameters
    ----------
    hard : Arrays
        The ordinary factors; the rows ``members`` are switched off (``NO_FACTOR``) in
        ``hard.factors``, which is changed during a call and restored before it returns.
    lo, hi : numpy.ndarray
        Bounds at the fixpoint of ``hard``; narrowed in place.
    members : numpy.ndarray
        Factor rows of the observations that may be outliers.
    block : numpy.ndarray
        The block of each of ``members``.
    allowance : numpy.ndarray
        The most outliers among ``members`` of each block (indexed by block).
    rtol, max_rounds
        As in :func:`~cuikslam.narrowing.propagation.narrow`.
    deadline : Budget, optional
        No block is started after this :func:`time.perf_counter` value.
    report : BlockBranching, optional
        Filled in; ``report.proven`` lists proven outliers as indices into ``members``.

    Returns
    -------
    Status
        ``Status.INCONSISTENT`` when some block has no surviving set: it holds more outliers
        than its allowance (a proof), else ``Status.CONSISTENT``.
    """
    report = report if report is not None else BlockBranching()
    ensure_round_to_nearest()
    factors = hard.factors
    original = factors[members, KIND].copy()
    work = _Work(hard, lo, hi)
    order = np.argsort(block, kind="stable")
    bounds = np.flatnonzero(np.diff(block[order])) + 1
    try:
        for group in np.split(order, bounds):
            if group.size == 0:
                continue
            p = int(allowance[block[group[0]]])
            k = group.size
            if p <= 0 or p >= k:
                continue
            if (
                math.comb(k, p) > MAX_SETS
                or report.sets + math.comb(k, p) > MAX_TOTAL
                or expired(deadline)
            ):
                report.skipped += 1
                continue
            status = _branch(hard, lo, hi, members[group], p, rtol, max_rounds, report, group, work)
            if status is Status.INCONSISTENT:
                return status
    finally:
        factors[members, KIND] = original
    return Status.CONSISTENT


class _Work:
    """Working bounds and the propagation's buffers, shared by every set of a call: a set
    costs what its propagation touches, not the size of the graph."""

    def __init__(self, hard: Arrays, lo: np.ndarray, hi: np.ndarray) -> None:
        n = hard.factors.shape[0]
        self.lo, self.hi = lo.copy(), hi.copy()
        self.queue = np.empty(n + 1, dtype=np.int64)
        self.state = np.zeros(n, dtype=np.int8)
        self.memory = fresh_memory(n)
        self.applied = np.empty(n, dtype=np.int64)
        self.hull_lo = np.full_like(lo, np.inf)
        self.hull_hi = np.full_like(hi, -np.inf)
        self.count = np.zeros(lo.shape[0], dtype=np.int64)

    def run(self, hard: Arrays, touched: np.ndarray, rtol: float, max_rounds: int):
        """Propagate from ``touched`` on the working bounds: (status, applications, the
        variables it may have changed)."""
        status, applications, n_applied = propagate_buffered(
            self.lo, self.hi, hard.factors, hard.head, hard.entry_factor, hard.entry_next,
            touched, float(rtol), int(max_rounds), 2**62, self.queue, self.state,
            self.memory, self.applied, False,
        )  # fmt: skip
        rows = hard.factors[self.applied[:n_applied], 1:].ravel()
        return status, applications, np.unique(rows[rows >= 0])


def _branch(
    hard: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    rows: np.ndarray,
    p: int,
    rtol: float,
    max_rounds: int,
    report: BlockBranching,
    group: np.ndarray,
    work: _Work,
) -> Status:
    """One block: every set of p outliers among ``rows``; the hull of the survivors.

    A variable no surviving set's propagation touched keeps its bounds (each such set
    leaves it as it is); the others get the hull of the sets' bounds.
    """
    k = rows.size
    in_every = np.ones(k, dtype=np.bool_)
    survived = 0
    seen = []
    report.blocks += 1
    for outliers in itertools.combinations(range(k), p):
        keep = np.ones(k, dtype=np.bool_)
        keep[list(outliers)] = False
        hard.factors[rows[keep], KIND] = OBSERVATION
        status, applications, changed = work.run(hard, rows[keep], rtol, max_rounds)
        hard.factors[rows[keep], KIND] = NO_FACTOR
        report.sets += 1
        report.applications += applications
        if status != INCONSISTENT:
            survived += 1
            in_every &= ~keep
            work.hull_lo[changed] = np.minimum(work.hull_lo[changed], work.lo[changed])
            work.hull_hi[changed] = np.maximum(work.hull_hi[changed], work.hi[changed])
            work.count[changed] += 1
            seen.append(changed)
        work.lo[changed] = lo[changed]  # back to the block's bounds
        work.hi[changed] = hi[changed]
    if survived == 0:
        return Status.INCONSISTENT
    if seen:
        every = np.unique(np.concatenate(seen))
        narrowed = every[work.count[every] == survived]
        lo[narrowed] = np.maximum(lo[narrowed], work.hull_lo[narrowed])
        hi[narrowed] = np.minimum(hi[narrowed], work.hull_hi[narrowed])
        work.lo[narrowed], work.hi[narrowed] = lo[narrowed], hi[narrowed]
        work.hull_lo[every], work.hull_hi[every], work.count[every] = np.inf, -np.inf, 0
    report.proven.extend(int(i) for i in group[in_every])
    return Status.CONSISTENT
