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

from cuikslam.budget import expired
from cuikslam.graph.encoding import KIND, NO_FACTOR, OBSERVATION
from cuikslam.narrowing.propagation import Arrays, Status, narrow

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
    deadline: float | None = None,
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
    deadline : float, optional
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
    factors = hard.factors
    original = factors[members, KIND].copy()
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
            status = _branch(hard, lo, hi, members[group], p, rtol, max_rounds, report, group)
            if status is Status.INCONSISTENT:
                return status
    finally:
        factors[members, KIND] = original
    return Status.CONSISTENT


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
) -> Status:
    """One block: every set of p outliers among ``rows``; the hull of the survivors."""
    k = rows.size
    hull_lo = np.full_like(lo, np.inf)
    hull_hi = np.full_like(hi, -np.inf)
    in_every = np.ones(k, dtype=np.bool_)
    survived = 0
    report.blocks += 1
    for outliers in itertools.combinations(range(k), p):
        keep = np.ones(k, dtype=np.bool_)
        keep[list(outliers)] = False
        hard.factors[rows[keep], KIND] = OBSERVATION
        part_lo, part_hi = lo.copy(), hi.copy()
        result = narrow(hard, part_lo, part_hi, rows[keep], rtol, max_rounds)
        hard.factors[rows[keep], KIND] = NO_FACTOR
        report.sets += 1
        report.applications += result.applications
        if result.is_empty:
            continue
        survived += 1
        np.minimum(hull_lo, part_lo, out=hull_lo)
        np.maximum(hull_hi, part_hi, out=hull_hi)
        in_every &= ~keep
    if survived == 0:
        return Status.INCONSISTENT
    np.maximum(lo, hull_lo, out=lo)
    np.minimum(hi, hull_hi, out=hi)
    report.proven.extend(int(i) for i in group[in_every])
    return Status.CONSISTENT
