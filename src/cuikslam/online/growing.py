"""A graph that grows as records arrive: bounds, factor rows and adjacency lists in arrays
whose capacity doubles when full, narrowed by waking only the factors a change touches.

The arrays are those of :mod:`cuikslam.graph.encoding` with spare capacity: rows past
``n_factors`` are ``NO_FACTOR`` and variables past ``n_variables`` belong to no factor, so
the compiled propagation (:func:`cuikslam.narrowing._propagate.propagate_buffered`) runs
on them as they are. Its work arrays are allocated once per capacity, so a narrowing costs
what it wakes, not the size of the graph, and adding a record costs O(1) amortised. The
bounds only ever shrink, so each factor keeps the memory of its auxiliary intervals from
one narrowing to the next (``keep_memory``): a propagation cut by a work limit and
resumed later converges as one left to run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.encoding import N_SLOTS, NO_FACTOR, factors_on, link_factor
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing._propagate import propagate_buffered
from cuikslam.narrowing.propagation import Arrays, Status

__all__ = ["GrowingGraph", "Narrowing"]

FIRST_CAPACITY = 256
"""Variables and factors the arrays hold before they first grow."""


@dataclass
class Narrowing:
    """What one call of :meth:`GrowingGraph.narrow` did."""

    status: Status
    applications: int
    deferred: np.ndarray
    """Factors to wake next time: those the work limit kept from running (empty at the
    fixpoint)."""


class GrowingGraph:
    """Bounds and factors of a graph that grows one record at a time.

    Examples
    --------
    >>> from cuikslam.graph.encoding import ODOMETRY
    >>> graph = GrowingGraph(rtol=1e-3)
    >>> inf = float("inf")
    >>> _ = graph.add_variables([0, 0, 0, -inf, -inf, -inf, 0, 1], [0, 0, 0, inf, inf, inf, 0, 2])
    >>> graph.add_factors([[ODOMETRY, 0, 1, 2, 3, 4, 5, 6, 7]]).tolist()
    [0]
    >>> result = graph.narrow(np.array([0]))
    >>> result.status, graph.lo[3:6].tolist(), graph.hi[3:6].tolist()
    (<Status.CONSISTENT: 0>, [0.9999999999999997, 0.0, 0.0], [2.0000000000000004, 0.0, 0.0])
    """

    def __init__(self, rtol: float, max_rounds: int = 1) -> None:
        self.rtol = float(rtol)
        self.max_rounds = int(max_rounds)
        self.n_variables = 0
        self.n_factors = 0
        self._n_entries = 0
        self.lo = np.empty(FIRST_CAPACITY)
        self.hi = np.empty(FIRST_CAPACITY)
        self.head = np.full(FIRST_CAPACITY, -1, dtype=np.int64)
        self._allocate_factors(FIRST_CAPACITY)

    # ------------------------------------------------------------------ growing
    def _allocate_factors(self, capacity: int) -> None:
        """(Re)size the factor table, the adjacency entries and the work arrays."""
        n, e = self.n_factors, self._n_entries
        factors = np.full((capacity, 1 + N_SLOTS), NO_FACTOR, dtype=np.int64)
        entry_factor = np.empty(N_SLOTS * capacity, dtype=np.int64)
        entry_next = np.empty(N_SLOTS * capacity, dtype=np.int64)
        if n:
            factors[:n] = self.factors[:n]
            entry_factor[:e], entry_next[:e] = self.entry_factor[:e], self.entry_next[:e]
        self.factors, self.entry_factor, self.entry_next = factors, entry_factor, entry_next
        memory = fresh_memory(capacity)
        if n:
            memory[:n] = self._memory[:n]
        self._queue = np.empty(capacity + 1, dtype=np.int64)
        self._state = np.zeros(capacity, dtype=np.int8)
        self._memory = memory
        self._applied = np.empty(capacity, dtype=np.int64)

    def _allocate_variables(self, capacity: int) -> None:
        """(Re)size the bounds and the adjacency heads."""
        first = self.n_variables
        self.lo = np.concatenate([self.lo[:first], np.empty(capacity - first)])
        self.hi = np.concatenate([self.hi[:first], np.empty(capacity - first)])
        head = np.full(capacity, -1, dtype=np.int64)
        head[:first] = self.head[:first]
        self.head = head

    @property
    def nearly_full(self) -> bool:
        """True when the variables or the factors fill more than 3/4 of their arrays."""
        return 4 * self.n_variables > 3 * len(self.lo) or 4 * self.n_factors > 3 * len(self.factors)

    def grow(self) -> None:
        """Double the capacity of whichever arrays are :attr:`nearly_full`, ahead of the
        records that would fill them (its cost, proportional to the graph, can then be
        paid when there is time)."""
        if 4 * self.n_variables > 3 * len(self.lo):
            self._allocate_variables(2 * len(self.lo))
        if 4 * self.n_factors > 3 * len(self.factors):
            self._allocate_factors(2 * len(self.factors))

    def add_variables(self, lo: np.ndarray, hi: np.ndarray) -> int:
        """New variables with these bounds; returns the index of the first."""
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        first, needed = self.n_variables, self.n_variables + len(lo)
        if needed > len(self.lo):
            self._allocate_variables(max(needed, 2 * len(self.lo)))
        self.lo[first:needed], self.hi[first:needed] = lo, hi
        self.n_variables = needed
        return first

    def add_factors(self, rows: np.ndarray) -> np.ndarray:
        """Append factor rows (shape (k, 9)) and link them; returns their indices."""
        rows = np.asarray(rows, dtype=np.int64).reshape(-1, 1 + N_SLOTS)
        first, needed = self.n_factors, self.n_factors + len(rows)
        if needed > len(self.factors):
            self._allocate_factors(max(needed, 2 * len(self.factors)))
        self.factors[first:needed] = rows
        for f in range(first, needed):
            self._n_entries = link_factor(
                self.factors[f], f, self.head, self.entry_factor, self.entry_next, self._n_entries
            )
        self.n_factors = needed
        return np.arange(first, needed, dtype=np.int64)

    # ------------------------------------------------------------------ narrowing
    def factors_of(self, variables: np.ndarray) -> np.ndarray:
        """The factors on any of ``variables`` (sorted, once each)."""
        variables = np.asarray(variables, dtype=np.int64)
        return np.unique(factors_on(variables, self.head, self.entry_factor, self.entry_next))

    def narrow(self, touched: np.ndarray, max_applications: int = 2**62) -> Narrowing:
        """Narrow the bounds in place from the factors ``touched`` (applied in this order,
        repeats ignored), waking only the factors whose variables they change, to the
        fixpoint or ``max_applications`` operator applications. Stopping early is sound;
        the factors it kept from running are returned as ``deferred``."""
        ensure_round_to_nearest()
        touched = np.asarray(touched, dtype=np.int64)
        status, applications, _ = propagate_buffered(
            self.lo, self.hi, self.factors, self.head, self.entry_factor, self.entry_next,
            touched, self.rtol, self.max_rounds, int(max_applications), self._queue,
            self._state, self._memory, self._applied, True,
        )  # fmt: skip
        status = Status(status)
        if status is Status.BUDGET_EXHAUSTED:  # the factors still queued come first
            left = self._queue[: int(np.argmax(self._queue < 0))].copy()
        else:
            left = self._queue[:0].copy()
        return Narrowing(status, int(applications), left)

    def arrays(self) -> Arrays:
        """The graph as the narrowing functions take it (views, without spare capacity)."""
        n, e = self.n_factors, self._n_entries
        return Arrays(
            self.factors[:n], self.head[: self.n_variables], self.entry_factor[:e],
            self.entry_next[:e],
        )  # fmt: skip
