"""The polytope-hull narrowing operator: each variable bounded over the linear relaxation
of the factors (:mod:`.relaxation`).

The LP solver works in floating point, so its optimum is not trusted: each bound is
re-derived from the LP's dual multipliers in interval arithmetic (Neumaier and
Shcherbina's safe bound, :mod:`.safe_bound`), which is valid for *any* multipliers. A
wrong or inaccurate LP answer can only make a bound weaker, never unsound
(:mod:`.lp_bounds`).
"""

from __future__ import annotations

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import Budget
from cuikslam.narrowing.lp_bounds import LpStatistics, WarmStarts, certified_bounds
from cuikslam.narrowing.propagation import Propagation, Status
from cuikslam.narrowing.relaxation import relax

__all__ = ["LpStatistics", "WarmStarts", "tighten"]


def _among(targets: np.ndarray, used: np.ndarray) -> np.ndarray:
    """The ``targets`` found in the sorted ``used``, in their order (the LPs' order)."""
    at = np.minimum(np.searchsorted(used, targets), max(len(used) - 1, 0))
    return targets[(len(used) > 0) & (used[at] == targets)] if len(used) else targets[:0]


def tighten(
    factors: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    targets: np.ndarray,
    warm: WarmStarts | None = None,
    *,
    deadline: Budget | None = None,
    statistics: LpStatistics | None = None,
    upper_targets: np.ndarray | None = None,
    reuse: bool = False,
) -> Propagation:
    """Narrow the ``targets`` variables, in place, to the hull of the linear relaxation of
    ``factors``.

    Only the variables of ``factors`` enter the LP (so a window of a long graph stays
    small): its cost depends on the size of ``factors`` and the targets only, not on the
    length of ``lo``. Pass the same ``warm`` to repeated calls on the same factors: each LP
    then starts from the optimal basis of its previous call, which the rows of a narrower
    box usually keep nearly optimal.

    Parameters
    ----------
    factors : ndarray
        Factor rows (see :mod:`cuikslam.graph.encoding`).
    lo, hi : ndarray
        Bounds of every variable; narrowed in place.
    targets : ndarray of int
        The variables to bound.
    warm : WarmStarts, optional
        Bases and multipliers of the previous calls on the same factors.
    deadline : Budget, optional
        A :func:`time.perf_counter` value past which no further LP starts (the remaining
        targets keep their bounds); each LP also runs within its own limits (see
        :mod:`.lp_bounds`).
    statistics : LpStatistics, optional
        Receives the LP counts.
    upper_targets : ndarray of int, optional
        With it, only the lower bounds of ``targets`` and the upper bounds of
        ``upper_targets`` are computed.
    reuse : bool
        No LP is solved: each bound is the safe bound of the multipliers of the same
        target's last LP in ``warm`` (see :func:`.lp_bounds.certified_bounds`).

    Returns
    -------
    Propagation
        Holding ``lo`` and ``hi`` themselves; ``Status.INCONSISTENT`` when the relaxation
        is proven empty (then the graph has no solution in the box), and no operator
        applications.
    """
    ensure_round_to_nearest()
    slots = factors[:, 1:]
    used = np.unique(slots[slots >= 0])  # sorted: a variable's column is its rank here
    local_factors = factors.copy()
    local_factors[:, 1:] = np.where(slots >= 0, np.searchsorted(used, np.maximum(slots, 0)), -1)
    relaxation = relax(local_factors, lo[used], hi[used])
    if relaxation.matrix.shape[0] == 0:
        return Propagation(lo, hi, Status.CONSISTENT, 0)
    box = np.stack([relaxation.col_lo, relaxation.col_hi], axis=-1)
    csc = relaxation.matrix.tocsc()
    upper_targets = targets if upper_targets is None else upper_targets
    chosen = _among(np.asarray(targets, dtype=np.int64), used)
    upper_chosen = _among(np.asarray(upper_targets, dtype=np.int64), used)
    # minima, then maxima, each with its own HiGHS instance
    warm = warm if warm is not None else WarmStarts()
    lower, upper = certified_bounds(
        csc, relaxation.row_lo, relaxation.row_hi, box,
        np.searchsorted(used, chosen).tolist(), warm, deadline, statistics,
        np.searchsorted(used, upper_chosen).tolist(), reuse,
    )  # fmt: skip
    if chosen.size:
        lo[chosen] = np.maximum(lo[chosen], lower)
    if upper_chosen.size:
        hi[upper_chosen] = np.minimum(hi[upper_chosen], upper)
    empty = np.any(lo[chosen] > hi[chosen]) or np.any(lo[upper_chosen] > hi[upper_chosen])
    return Propagation(lo, hi, Status.INCONSISTENT if empty else Status.CONSISTENT, 0)
