"""Narrowing when some observations may be outliers: the q-relaxed intersection.

The user declares that at most q observations are outliers (their interval misses the
truth), in the whole log and/or in each block of poses. The observation rows that may be
outliers (*members*) leave the ordinary propagation; every other factor stays. For each
variable the members touch, at least k - q of its k members' contractions hold the truth
(q: the most outliers the declaration allows among those k members), so the variable is
narrowed to their q-relaxed intersection (:mod:`._relaxed`). The boxes then hold the
truth whenever the declaration does.

A member with no solution in such a box is a *proven outlier* (its interval cannot hold
the truth). It is taken out of the members and the allowance of its scope drops by one;
a member whose scope has no allowance left cannot be an outlier and becomes an ordinary
factor; then everything is narrowed again, until no new outlier is proven. More proven
outliers than declared is a proof that the log breaks its declaration.

The possible sets of outliers are then enumerated (:mod:`.outlier_blocks`: the hull over
the sets that survive, and a proof for an observation in every one of them), in each block
of poses with a bound per block, and in the whole log when it has few enough sets (C(k, q)
at most ``outlier_blocks.MAX_SETS``). This restores much of what the per-variable rule
loses on variables seen by few observations; it runs before the stronger level, which has
the time budget. The stronger levels (``lp``, ``lp-split``) see only the ordinary factors:
the members are left out of the polytope (sound, only less tight), and the relaxed
intersection runs again after them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cuikslam.budget import Budget, expired
from cuikslam.graph.encoding import KIND, NO_FACTOR, TA, factors_on
from cuikslam.narrowing._relaxed import (
    RELAXED_INCONSISTENT,
    SHARED_SLOTS,
    member_contractions,
    relaxed_meet,
)
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.outlier_blocks import BlockBranching, branch_on_blocks
from cuikslam.narrowing.propagation import Arrays, Propagation, Status, narrow

__all__ = ["NO_LIMIT", "OutlierScope", "RelaxedReport", "narrow_with_outliers"]

NO_LIMIT = 2**40
"""The allowance of a scope the declaration does not bound."""
MEMBER_ROUNDS = 8
"""Local rounds of a member's operator when it computes its contraction."""
BRANCH_ROUNDS = 3
"""Rounds of branching on the blocks per pass at most (each until it gains under 1 %)."""
MAX_SWEEPS = 400
"""Relaxed intersections per fixpoint at most (stopping earlier is sound, only wider)."""


@dataclass
class OutlierScope:
    """Which observation rows may be outliers, and how many.

    ``members`` are indices of ``OBSERVATION`` rows of the factor table. ``at_most``
    bounds the outliers among all of them (``NO_LIMIT``: no such bound); ``block[i]`` is
    member i's block of poses, holding at most ``per_block`` outliers (``NO_LIMIT``: no
    such bound; then every ``block`` may be 0).
    """

    members: np.ndarray
    block: np.ndarray
    at_most: int = NO_LIMIT
    per_block: int = NO_LIMIT


@dataclass
class RelaxedReport:
    """What :func:`narrow_with_outliers` proved."""

    proven: list[int] = field(default_factory=list)
    """Members (indices into ``OutlierScope.members``) proven outliers, in the order found."""
    exceeded: bool = False
    """True when the box is empty: more members are outliers than the declaration allows."""
    passes: int = 0
    """Narrowings run (one, plus one per round of newly proven outliers)."""
    sweeps: int = 0
    """Relaxed intersections applied, over all passes."""
    branched_blocks: int = 0
    """Blocks of poses whose sets of outliers were enumerated (:mod:`.outlier_blocks`)."""
    branched_sets: int = 0
    """Sets of outliers tried in those blocks."""
    skipped_blocks: int = 0
    """Blocks left to the relaxed rule alone (too many sets, or out of time), at most in a
    round."""
    strengthen: StrengthenReport = field(default_factory=StrengthenReport)
    """The stronger level's report (of its last run)."""


def narrow_with_outliers(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    scope: OutlierScope,
    level: str = "hull",
    rtol: float = 1e-3,
    max_rounds: int = 1,
    *,
    deadline: Budget | None = None,
    report: RelaxedReport | None = None,
    threads: int | None = None,
) -> Propagation:
    """Narrow ``lo``/``hi`` in place, sound whenever the declaration of ``scope`` holds.

    Parameters
    ----------
    arrays : Arrays
        The whole graph, members included.
    lo, hi : numpy.ndarray
        Initial bounds of every variable; narrowed in place.
    scope : OutlierScope
        The observation rows that may be outliers and the declared allowances.
    level : str
        ``hull``, ``lp`` or ``lp-split``: the stronger level, run on the ordinary factors.
    rtol, max_rounds
        As in :func:`~cuikslam.narrowing.propagation.narrow`.
    deadline : Budget, optional
        A :func:`time.perf_counter` value for the stronger level (as in
        :func:`~cuikslam.narrowing.consistency.strengthen`).
    report : RelaxedReport, optional
        Filled in with the proven outliers.
    threads : int, optional
        Threads of the stronger level's sweeps (as in
        :func:`~cuikslam.narrowing.consistency.strengthen`).

    Returns
    -------
    Propagation
        ``Status.INCONSISTENT`` is a proof that more observations are outliers than
        declared (or that another record misses its truth); ``report.exceeded`` says so.
    """
    report = report if report is not None else RelaxedReport()
    n = scope.members.size
    active = np.ones(n, dtype=np.bool_)
    n_blocks = int(scope.block.max()) + 1 if n else 1
    block_left = np.full(n_blocks, scope.per_block, dtype=np.int64)
    left = scope.at_most
    applications = 0
    while True:
        report.passes += 1
        allowance = np.minimum(left, block_left[scope.block])
        relaxed = active & (allowance > 0)
        factors = arrays.factors.copy()
        factors[scope.members[~active | relaxed], KIND] = NO_FACTOR
        hard = Arrays(factors, arrays.head, arrays.entry_factor, arrays.entry_next)
        meet = _RelaxedMeet(arrays.factors, scope, relaxed, left, block_left, rtol)
        status, count = _fixpoint(hard, meet, lo, hi, None, rtol, max_rounds, report)
        applications += count
        branched: list[int] = []
        if status is not Status.INCONSISTENT and relaxed.any():
            status, branched, count = _branch(
                hard, meet, lo, hi, scope, relaxed, left, np.minimum(block_left, left), rtol,
                max_rounds, deadline, report,
            )  # fmt: skip
            applications += count
        if status is not Status.INCONSISTENT and level != "hull" and not expired(deadline):
            status, count = _strengthen(
                hard, meet, lo, hi, level, rtol, max_rounds, deadline, report, threads
            )
            applications += count
        if status is Status.INCONSISTENT:
            report.exceeded = True
            return Propagation(lo, hi, Status.INCONSISTENT, applications)
        empty = np.zeros(n, dtype=np.bool_)
        empty[relaxed] = meet.contract(lo, hi, write=False)
        empty[branched] = True
        new = np.flatnonzero(empty)
        if new.size == 0:
            return Propagation(lo, hi, Status.CONSISTENT, applications)
        report.proven.extend(int(i) for i in new)
        active[new] = False
        left -= new.size
        np.subtract.at(block_left, scope.block[new], 1)
        if left < 0 or (block_left < 0).any():
            report.exceeded = True
            return Propagation(lo, hi, Status.INCONSISTENT, applications)


class _RelaxedMeet:
    """The members still relaxed, compiled for :func:`._relaxed.relaxed_meet`."""

    def __init__(
        self,
        factors: np.ndarray,
        scope: OutlierScope,
        relaxed: np.ndarray,
        left: int,
        block_left: np.ndarray,
        rtol: float,
    ) -> None:
        self.rows = factors[scope.members[relaxed]]
        self.rtol = rtol
        n = self.rows.shape[0]
        self.out_lo = np.empty((n, len(SHARED_SLOTS)))
        self.out_hi = np.empty((n, len(SHARED_SLOTS)))
        self.empty = np.zeros(n, dtype=np.bool_)
        self.everyone = np.ones(n, dtype=np.bool_)
        slots = np.array(SHARED_SLOTS)
        variable = self.rows[:, slots].ravel()
        member = np.repeat(np.arange(n), len(slots))
        slot = np.tile(np.arange(len(slots)), n)
        block = scope.block[relaxed][member]
        order = np.lexsort((member, block, variable))
        variable, member, slot, block = variable[order], member[order], slot[order], block[order]
        self.entry_member = member.astype(np.int64)
        self.entry_slot = slot.astype(np.int64)
        # one group per variable (all its members; the most outliers among them: the
        # global allowance, or the sum of their blocks' allowances) ...
        variables, starts = np.unique(variable, return_index=True)
        ends = np.append(starts[1:], variable.size)
        which = np.repeat(np.arange(variables.size), ends - starts)
        pairs, pair_starts = np.unique(np.stack([which, block]), axis=1, return_index=True)
        per_variable = np.zeros(variables.size, dtype=np.int64)
        np.add.at(per_variable, pairs[0], block_left[pairs[1]])
        groups = [(variables, starts, ends, np.minimum(per_variable, left))]
        # ... and, with a bound per block, one per variable and block
        if scope.per_block < NO_LIMIT and pairs.shape[1] > variables.size:
            pair_ends = np.append(pair_starts[1:], variable.size)
            groups.append(
                (variables[pairs[0]], pair_starts, pair_ends,
                 np.minimum(block_left[pairs[1]], left))
            )  # fmt: skip
        self.variables = np.concatenate([g[0] for g in groups]).astype(np.int64)
        self.starts = np.concatenate([g[1] for g in groups]).astype(np.int64)
        self.ends = np.concatenate([g[2] for g in groups]).astype(np.int64)
        self.allowance = np.concatenate([g[3] for g in groups]).astype(np.int64)
        self.is_angle = np.isin(self.variables, self.rows[:, TA])
        self.changed = np.zeros(self.variables.size, dtype=np.bool_)

    def contract(self, lo: np.ndarray, hi: np.ndarray, *, write: bool) -> np.ndarray:
        """Each member's contraction from the box; returns which have no solution."""
        member_contractions(
            lo, hi, self.rows, self.everyone, self.rtol, MEMBER_ROUNDS,
            self.out_lo, self.out_hi, self.empty, write,
        )  # fmt: skip
        return self.empty

    def __call__(self, lo: np.ndarray, hi: np.ndarray) -> tuple[bool, np.ndarray]:
        """One relaxed intersection: (consistent, the variables it narrowed)."""
        self.contract(lo, hi, write=True)
        status = relaxed_meet(
            lo, hi, self.variables, self.is_angle, self.allowance, self.starts, self.ends,
            self.entry_member, self.entry_slot, self.out_lo, self.out_hi, self.empty,
            self.rtol, self.changed,
        )  # fmt: skip
        return status != RELAXED_INCONSISTENT, self.variables[self.changed]


def _strengthen(
    hard: Arrays,
    meet: _RelaxedMeet,
    lo: np.ndarray,
    hi: np.ndarray,
    level: str,
    rtol: float,
    max_rounds: int,
    deadline: Budget | None,
    report: RelaxedReport,
    threads: int | None = None,
) -> tuple[Status, int]:
    """The stronger level on the ordinary factors, then the relaxed fixpoint again."""
    strong = strengthen(
        hard, lo, hi, level, rtol, max_rounds, deadline=deadline, report=report.strengthen,
        threads=threads,
    )  # fmt: skip
    if strong.status is Status.INCONSISTENT:
        return strong.status, strong.applications
    status, count = _fixpoint(hard, meet, lo, hi, [], rtol, max_rounds, report)
    return status, strong.applications + count


def _branch(
    hard: Arrays,
    meet: _RelaxedMeet,
    lo: np.ndarray,
    hi: np.ndarray,
    scope: OutlierScope,
    relaxed: np.ndarray,
    left: int,
    allowance: np.ndarray,
    rtol: float,
    max_rounds: int,
    deadline: Budget | None,
    report: RelaxedReport,
) -> tuple[Status, list[int], int]:
    """Branch on the outliers of the whole log (when few enough sets) and of each block
    (:mod:`.outlier_blocks`), then narrow again.

    Returns the status, the members proven outliers and the operator applications.
    """
    which = np.flatnonzero(relaxed)
    scopes = []  # (block of each member, allowance of each block)
    if left < NO_LIMIT:
        scopes.append((np.zeros(which.size, dtype=np.int64), np.array([left])))
    if scope.per_block < NO_LIMIT:
        scopes.append((scope.block[which], allowance))
    proven: set[int] = set()
    applications = 0
    status = Status.CONSISTENT
    for _ in range(BRANCH_ROUNDS):
        branching = BlockBranching()
        before = _width(lo, hi)
        for blocks, allowed in scopes:
            status = branch_on_blocks(
                hard, lo, hi, scope.members[which], blocks, allowed, rtol, max_rounds,
                deadline, branching,
            )  # fmt: skip
            if status is Status.INCONSISTENT:
                break
        report.branched_blocks += branching.blocks
        report.branched_sets += branching.sets
        report.skipped_blocks = max(report.skipped_blocks, branching.skipped)
        applications += branching.applications
        proven.update(int(which[i]) for i in branching.proven)
        if status is Status.INCONSISTENT:
            return status, [], applications
        after = _width(lo, hi)
        if after == before:
            break
        status, count = _fixpoint(hard, meet, lo, hi, None, rtol, max_rounds, report)
        applications += count
        if status is Status.INCONSISTENT or proven or _width(lo, hi) > 0.99 * before:
            break
    return status, sorted(proven), applications


def _width(lo: np.ndarray, hi: np.ndarray) -> float:
    """The sum of the finite widths (a measure of progress, not of soundness; huge widths
    may sum to inf, which then reads as no progress)."""
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf: not finite, left out
        widths = hi - lo
        return float(widths[np.isfinite(widths)].sum())


def _fixpoint(
    hard: Arrays,
    meet: _RelaxedMeet,
    lo: np.ndarray,
    hi: np.ndarray,
    touched: list[int] | None,
    rtol: float,
    max_rounds: int,
    report: RelaxedReport,
) -> tuple[Status, int]:
    """Alternate the ordinary propagation and the relaxed intersection until neither
    narrows (or ``MAX_SWEEPS`` intersections ran)."""
    applications = 0
    first = None if touched is None else np.asarray(touched, dtype=np.int64)
    result = narrow(hard, lo, hi, first, rtol, max_rounds)
    applications += result.applications
    if result.is_empty:
        return Status.INCONSISTENT, applications
    for _ in range(MAX_SWEEPS):
        if meet.rows.shape[0] == 0:
            break
        report.sweeps += 1
        consistent, changed = meet(lo, hi)
        if not consistent:
            return Status.INCONSISTENT, applications
        if changed.size == 0:
            break
        touched_now = np.unique(factors_on(changed, hard.head, hard.entry_factor, hard.entry_next))
        result = narrow(hard, lo, hi, touched_now, rtol, max_rounds)
        applications += result.applications
        if result.is_empty:
            return Status.INCONSISTENT, applications
    return Status.CONSISTENT, applications
