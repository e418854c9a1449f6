"""Declared outliers with unknown correspondence: "outlier" as one more option of a decision.

A log may declare that at most q of its observations miss their truth (``outliers``
records, ``docs/log-format.md``). In the correspondence search an unlabelled observation
then has one more option after its candidate landmarks and "a new landmark": *outlier*, the
observation explains nothing and adds no constraint. The option is open while the node's
path stays within the declaration: at most ``at_most`` outlier decisions in all, and with
a window at most ``per_block`` in each block of poses (the blocks of
:meth:`cuikslam.log.records.Log.pose_order`, as with known correspondence). Both counts are
functions of the path only, so exploring a subtree stays a function of its prefix.

The declaration's budget is not shared between the two kinds of observations: the
unlabelled ones get the whole declaration in the search, and the named ones of the same
log get it too in the q-relaxed intersection at the root (:func:`relax_named`). Sound,
only weaker than sharing it.

An outlier is a detection whose value is wrong: the landmark it truly detected may be none
(a phantom) or any landmark in view. Negative information (UNSEEN constraints) is therefore
left out for every pose with an outlier decision on the node's path, and for every pose with
a named observation (which may be an outlier too); named landmarks of a scan exclude
nothing from its unlabelled observations.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cuikslam.graph.encoding import N_SLOTS
from cuikslam.hypotheses._shared import linked
from cuikslam.log.records import Log
from cuikslam.narrowing.outliers import NO_LIMIT, OutlierScope, RelaxedReport, narrow_with_outliers
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, Status

__all__ = ["OUTLIER", "OutlierOption", "outlier_option", "relax_named"]

OUTLIER = -1
"""The landmark number of the outlier option in a node's decisions."""


@dataclass(frozen=True)
class OutlierOption:
    """The declaration as the search applies it."""

    at_most: int = NO_LIMIT
    """Outlier decisions on a path at most."""
    per_block: int = NO_LIMIT
    """Outlier decisions per block of poses at most."""
    block: tuple[int, ...] = ()
    """Block of poses of each decision (all 0 without a window)."""
    tainted: frozenset[int] = field(default_factory=frozenset)
    """Poses with a named observation: no UNSEEN constraint on them (it may be an outlier)."""
    member_block: tuple[int, ...] = ()
    """Block of poses of each named observation (for :func:`relax_named`)."""

    def allows(self, outliers: tuple[int, ...], k: int) -> bool:
        """Whether decision ``k`` may be an outlier after the outlier decisions
        ``outliers`` of its path."""
        if len(outliers) >= self.at_most:
            return False
        if self.per_block >= NO_LIMIT:
            return True
        b = self.block[k]
        return sum(1 for j in outliers if self.block[j] == b) < self.per_block


def outlier_option(log: Log, decision_poses: Sequence[int]) -> OutlierOption | None:
    """The declaration of ``log`` for decisions made from ``decision_poses`` (None when the
    log declares no outliers)."""
    bounds = log.outlier_bounds
    if not bounds:
        return None
    at_most, per_block, window = NO_LIMIT, NO_LIMIT, None
    for bound in bounds:
        if bound.window is None:
            at_most = bound.at_most
        else:
            per_block, window = bound.at_most, bound.window
    rank = log.pose_order()
    named = [o.pose for o in log.observations if o.landmark is not None]

    def block(pose: int) -> int:
        return 0 if window is None else rank[pose] // window

    return OutlierOption(
        at_most=at_most,
        per_block=per_block,
        block=tuple(block(p) for p in decision_poses),
        tainted=frozenset(named),
        member_block=tuple(block(p) for p in named),
    )


def relax_named(
    rows: np.ndarray,
    members: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    option: OutlierOption,
    rtol: float,
) -> tuple[np.ndarray, RelaxedReport]:
    """Narrow ``lo``/``hi`` in place with the named observations' rows (``members``, indices
    into ``rows``) under the q-relaxed intersection of the declaration; every other row
    holds. Returns the rows left for the search (the members taken out: they narrow only
    here, at the root) and the report (proven outliers: indices into ``members``;
    ``exceeded``: the declaration is broken whatever the correspondence)."""
    rows = np.asarray(rows, dtype=np.int64).reshape(-1, 1 + N_SLOTS)
    scope = OutlierScope(
        members=np.asarray(members, dtype=np.int64),
        block=np.array(option.member_block, dtype=np.int64),
        at_most=option.at_most,
        per_block=option.per_block,
    )
    report = RelaxedReport()
    result = narrow_with_outliers(
        linked(rows, len(lo)), lo, hi, scope, "hull", rtol, DEFAULT_ROUNDS, report=report
    )
    report.exceeded = report.exceeded or result.status is Status.INCONSISTENT
    keep = np.ones(len(rows), dtype=np.bool_)
    keep[scope.members] = False
    return rows[keep], report
