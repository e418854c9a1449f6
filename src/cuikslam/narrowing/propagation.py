"""Propagation: narrow a graph's boxes to the fixpoint of its factors' narrowing operators."""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing._propagate import (
    BUDGET_EXHAUSTED,
    CONSISTENT,
    INCONSISTENT,
    propagate_arrays,
)
from cuikslam.options import SolveOptions

__all__ = ["DEFAULT_RTOL", "Propagation", "Status", "propagate"]

DEFAULT_RTOL = SolveOptions.rtol
"""A variable that shrinks by less than this fraction of its width wakes nobody."""
DEFAULT_ROUNDS = 1
"""Repetitions of a factor's sub-operators per application (its local fixpoint)."""


class Status(enum.Enum):
    """Outcome of a propagation."""

    CONSISTENT = CONSISTENT
    """Fixpoint reached; the boxes enclose every solution."""
    INCONSISTENT = INCONSISTENT
    """Proof that the constraints have no solution."""
    BUDGET_EXHAUSTED = BUDGET_EXHAUSTED
    """Stopped before the fixpoint; the boxes still enclose every solution."""


@dataclass
class Propagation:
    """The narrowed bounds of every variable, and how they were obtained."""

    lo: np.ndarray
    hi: np.ndarray
    status: Status
    applications: int

    @property
    def is_empty(self) -> bool:
        return self.status is Status.INCONSISTENT


def propagate(
    graph: KinematicGraph,
    lo: np.ndarray | None = None,
    hi: np.ndarray | None = None,
    touched: np.ndarray | None = None,
    rtol: float = DEFAULT_RTOL,
    max_rounds: int = DEFAULT_ROUNDS,
    max_applications: int = 2**62,
) -> Propagation:
    """Narrow the boxes of ``graph`` to the fixpoint of its narrowing operators.

    Parameters
    ----------
    graph : KinematicGraph
    lo, hi : ndarray, optional
        Starting bounds (copied, not modified); the graph's initial domains by default.
    touched : ndarray of int, optional
        Factors to apply first (incremental propagation); all factors by default.
    rtol : float
        Relative shrink below which a variable wakes no other factor.
    max_rounds : int
        Local repetitions of a factor's sub-operators.
    max_applications : int
        Budget of operator applications.
    """
    ensure_round_to_nearest()
    if lo is None or hi is None:
        lo, hi = graph.domains()
    else:
        lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    factors = graph.factor_table()
    if touched is None:
        touched = np.arange(factors.shape[0], dtype=np.int64)
    head, entry_factor, entry_next = graph.adjacency()
    status, applications = propagate_arrays(
        lo,
        hi,
        factors,
        head,
        entry_factor,
        entry_next,
        np.asarray(touched, dtype=np.int64),
        float(rtol),
        int(max_rounds),
        int(max_applications),
    )
    return Propagation(lo, hi, Status(status), int(applications))
