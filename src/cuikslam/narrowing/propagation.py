"""Propagation: narrow a graph's boxes to the fixpoint of its factors' narrowing operators.

This module also holds the narrowing protocol every level follows: a narrowing function
takes the compiled graph (:class:`Arrays`) and the bounds ``lo``/``hi``, narrows them in
place, and returns a :class:`Propagation` holding those same arrays, a :class:`Status`
and the count of operator applications (:func:`narrow` here,
:func:`.consistency.strengthen`, :func:`.polytope.tighten`). :func:`propagate` is the
entry point on a :class:`KinematicGraph`: it copies the bounds, then narrows the copies.
The kernels' integer codes stay inside the kernels and this module.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.encoding import factors_on
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing._propagate import (
    BUDGET_EXHAUSTED,
    CONSISTENT,
    INCONSISTENT,
    propagate_arrays,
)
from cuikslam.options import SolveOptions

__all__ = ["DEFAULT_RTOL", "Arrays", "Propagation", "Status", "narrow", "propagate"]

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
class Arrays:
    """A graph as the compiled kernels see it (see :mod:`cuikslam.graph.encoding`)."""

    factors: np.ndarray
    head: np.ndarray
    entry_factor: np.ndarray
    entry_next: np.ndarray

    @classmethod
    def of(cls, graph: KinematicGraph) -> Arrays:
        """The factor table and adjacency lists of ``graph``."""
        head, entry_factor, entry_next = graph.adjacency()
        return cls(graph.factor_table(), head, entry_factor, entry_next)

    def factors_of(self, variable: int) -> np.ndarray:
        """The factors on ``variable`` (by walking its adjacency list)."""
        variables = np.array([variable], dtype=np.int64)
        return factors_on(variables, self.head, self.entry_factor, self.entry_next)


@dataclass
class Propagation:
    """The narrowed bounds of every variable, and how they were obtained.

    ``lo`` and ``hi`` are indexed like the graph's variables; :meth:`pose_box` and
    :meth:`landmark_box` read them by pose id and landmark id.

    Examples
    --------
    >>> from cuikslam.graph import KinematicGraph
    >>> graph = KinematicGraph()
    >>> graph.add_pose_prior(0, x=(0, 0), y=(0, 0), theta=(0, 0))
    >>> _ = graph.add_odometry(0, 1, turn=(0, 0), distance=(1, 2))
    >>> result = propagate(graph)
    >>> result.pose_box(1).tolist()  # x in [1, 2], widened by the outward rounding of cos
    [[0.9999999999999997, 2.0000000000000004], [0.0, 0.0], [0.0, 0.0]]
    """

    lo: np.ndarray
    hi: np.ndarray
    status: Status
    applications: int
    graph: KinematicGraph | None = field(default=None, repr=False, compare=False)
    """The graph whose variables these are (None: unknown)."""

    @property
    def is_empty(self) -> bool:
        return self.status is Status.INCONSISTENT

    def pose_box(self, pose: int) -> np.ndarray:
        """The (3, 2) box of ``pose``: (x, y, theta) × (lo, hi)."""
        i = self._graph().pose_index(pose)
        return np.stack([self.lo[i : i + 3], self.hi[i : i + 3]], axis=-1)

    def landmark_box(self, landmark: str) -> np.ndarray:
        """The (2, 2) box of ``landmark``: (x, y) × (lo, hi)."""
        i = self._graph().landmark_index(landmark)
        return np.stack([self.lo[i : i + 2], self.hi[i : i + 2]], axis=-1)

    def _graph(self) -> KinematicGraph:
        if self.graph is None:
            raise ValueError("this propagation does not know its graph")
        return self.graph


def narrow(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    touched: np.ndarray | None = None,
    rtol: float = DEFAULT_RTOL,
    max_rounds: int = DEFAULT_ROUNDS,
    max_applications: int = 2**62,
) -> Propagation:
    """Narrow ``lo``/``hi`` in place to the fixpoint of the narrowing operators of ``arrays``.

    Parameters
    ----------
    arrays : Arrays
        The graph, compiled.
    lo, hi : ndarray
        Bounds of every variable (float64); narrowed in place.
    touched : ndarray of int, optional
        Factors to apply first (incremental propagation); all factors by default.
    rtol : float
        Relative shrink below which a variable wakes no other factor.
    max_rounds : int
        Local repetitions of a factor's sub-operators.
    max_applications : int
        Budget of operator applications.

    Returns
    -------
    Propagation
        Holding ``lo`` and ``hi`` themselves; ``Status.INCONSISTENT`` is a proof that no
        solution lies in the box.
    """
    ensure_round_to_nearest()
    if touched is None:
        touched = np.arange(arrays.factors.shape[0], dtype=np.int64)
    status, applications = propagate_arrays(
        lo, hi, arrays.factors, arrays.head, arrays.entry_factor, arrays.entry_next,
        np.asarray(touched, dtype=np.int64), float(rtol), int(max_rounds),
        int(max_applications),
    )  # fmt: skip
    return Propagation(lo, hi, Status(status), int(applications))


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
    touched, rtol, max_rounds, max_applications
        As in :func:`narrow`.

    Returns
    -------
    Propagation
        The narrowed copies, which answer :meth:`Propagation.pose_box` and
        :meth:`Propagation.landmark_box`.
    """
    ensure_round_to_nearest()
    if lo is None or hi is None:
        lo, hi = graph.domains()
    else:
        lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    result = narrow(Arrays.of(graph), lo, hi, touched, rtol, max_rounds, max_applications)
    result.graph = graph
    return result
