"""Storage shared by every live hypothesis: one base graph, and a small overlay per branch.

Live hypotheses (branches) differ from each other in a few tens of variables and factors,
so none holds a full copy of the graph. Shared by all:

- the *base boxes*: reference bounds of every variable;
- the *factor pool*: every distinct factor row that some branch holds, stored once, with
  one adjacency over them all. Rows of the *base set* belong to every live branch.

A branch holds an :class:`Overlay`: the variables whose bounds differ from the base, and
the pool rows it holds beyond the base set. Overlays are never modified, so a child shares
its parent's arrays until it changes something.

To work on a branch it is *checked out*: its bounds are written over the base in working
arrays and its rows are switched on; switching costs the two overlays, not the graph. A
child (the branch plus some factors) is propagated on the working arrays by the same
compiled kernel as a full graph; the variables it changed become the child's overlay and
the working arrays are put back. Rows of other branches stay in the adjacency but read as
``NO_FACTOR``, which propagation skips, so the result is bit for bit what a private copy
of the branch, with its rows in pool order, would give (:meth:`SharedGraph.standalone`).

Now and then the base moves to the bounds most branches have, rows that every branch
holds join the base set, and rows that no live branch holds leave the pool
(:meth:`SharedGraph.maintain`). None of this changes any branch's boxes or rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuikslam import interval as ia
from cuikslam.graph import encoding as enc
from cuikslam.graph.encoding import KIND, N_SLOTS, NO_FACTOR, factors_on
from cuikslam.hypotheses import _kernels as k
from cuikslam.hypotheses._gates import gate_many, pairs_within_reach
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing.propagation import Arrays, Status

__all__ = ["EMPTY_OVERLAY", "Overlay", "SharedGraph"]

MIN_MAINTENANCE_LOAD = 4096
"""Overlay entries (summed over branches) and pool rows below which nothing is maintained."""


@dataclass(frozen=True, slots=True)
class Overlay:
    """What one branch holds beyond the shared base: never modified once built."""

    idx: np.ndarray
    """Sorted variables whose bounds differ from the base boxes."""
    lo: np.ndarray
    hi: np.ndarray
    rows: np.ndarray
    """Sorted pool rows that this branch holds beyond the base set."""

    @property
    def size(self) -> int:
        return len(self.idx) + len(self.rows)

    @property
    def nbytes(self) -> int:
        return self.idx.nbytes + self.lo.nbytes + self.hi.nbytes + self.rows.nbytes


_NO_INT = np.zeros(0, dtype=np.int64)
EMPTY_OVERLAY = Overlay(_NO_INT, np.zeros(0), np.zeros(0), _NO_INT)


class SharedGraph:
    """Base boxes, the factor pool, and working arrays for one branch at a time.

    Every branch operation takes the branch's :class:`Overlay` as an argument and returns
    a new overlay; the working arrays (``lo``/``hi``: base + one overlay) are an internal
    cache. ``ranked`` are the variables whose widths rank branches (poses).
    """

    def __init__(
        self, lo: np.ndarray, hi: np.ndarray, ranked: np.ndarray, rtol: float, max_rounds: int
    ) -> None:
        self.rtol = rtol
        self.max_rounds = max_rounds
        self.base_lo = np.array(lo, dtype=np.float64)
        self.base_hi = np.array(hi, dtype=np.float64)
        self.lo, self.hi = self.base_lo.copy(), self.base_hi.copy()
        self._saved_lo, self._saved_hi = self.base_lo.copy(), self.base_hi.copy()
        """Base + checked-out overlay, without a trial's changes."""
        self._mark = np.zeros(len(lo), dtype=np.bool_)
        self._ranked = np.zeros(len(lo), dtype=np.bool_)
        self._ranked[ranked] = True
        self._ranked_base = self._base_widths()
        self.current = EMPTY_OVERLAY
        self.applications = 0
        self.n_rows = 0
        self.n_entries = 0
        self.head = np.full(len(lo), -1, dtype=np.int64)
        self._allocate(1024)
        self._table = k.rehash(self.rows, self.kinds, 0, 4096)
        self._live_after_compaction = 0
        self._load_after_rebase = 0
        self.maintenances = 0
        """Rebases and compactions :meth:`maintain` made: each moves the base or the pool
        under the overlays it was not given."""

    # ------------------------------------------------------------------ the pool
    def _allocate(self, capacity: int) -> None:
        """(Re)size the pool and the propagation's work arrays to ``capacity`` rows."""
        n, e = self.n_rows, self.n_entries
        rows = np.full((capacity, 1 + N_SLOTS), NO_FACTOR, dtype=np.int64)
        kinds = np.full(capacity, NO_FACTOR, dtype=np.int64)
        in_base = np.zeros(capacity, dtype=np.bool_)
        entry_factor = np.zeros(N_SLOTS * capacity, dtype=np.int64)
        entry_next = np.zeros(N_SLOTS * capacity, dtype=np.int64)
        if n:
            rows[:n], kinds[:n], in_base[:n] = self.rows[:n], self.kinds[:n], self.in_base[:n]
            entry_factor[:e], entry_next[:e] = self.entry_factor[:e], self.entry_next[:e]
        self.rows, self.kinds, self.in_base = rows, kinds, in_base
        self.entry_factor, self.entry_next = entry_factor, entry_next
        self._queue = np.empty(capacity + 1, dtype=np.int64)
        self._state = np.zeros(capacity, dtype=np.int8)
        self._memory = fresh_memory(capacity)
        self._applied = np.empty(capacity, dtype=np.int64)

    def intern(self, rows: np.ndarray) -> np.ndarray:
        """Pool ids of factor rows (shape (k, 9)); rows not pooled yet are added, switched off."""
        rows = np.ascontiguousarray(rows, dtype=np.int64).reshape(-1, 1 + N_SLOTS)
        needed = self.n_rows + len(rows)
        if needed > len(self.kinds):
            self._allocate(max(needed, 2 * len(self.kinds)))
        if 2 * needed > len(self._table):
            size = 1 << int(4 * needed - 1).bit_length()
            self._table = k.rehash(self.rows, self.kinds, self.n_rows, size)
        ids, self.n_rows, self.n_entries = k.intern(
            rows, self.rows, self.kinds, self.n_rows, self._table, self.head,
            self.entry_factor, self.entry_next, self.n_entries,
        )  # fmt: skip
        return ids

    def add_to_base(self, ids: np.ndarray) -> None:
        """Rows that every live branch holds from now on (e.g. an odometry factor)."""
        self.in_base[ids] = True
        self.rows[ids, KIND] = self.kinds[ids]

    def factors_of(self, variables: np.ndarray) -> np.ndarray:
        """Sorted pool rows (switched on or not) that involve any of ``variables``."""
        return np.unique(factors_on(variables, self.head, self.entry_factor, self.entry_next))

    # ------------------------------------------------------------- branch operations
    # Every operation names the branch (overlay) it works on; which one the working arrays
    # hold is private, so no caller can act on another branch by mistake.
    def _checkout(self, overlay: Overlay) -> None:
        """Make the working arrays hold the branch of ``overlay``."""
        if overlay is self.current:
            return
        old = self.current
        k.switch(
            self.lo, self.hi, self._saved_lo, self._saved_hi, self.base_lo, self.base_hi,
            old.idx, overlay.idx, overlay.lo, overlay.hi, self.rows, self.kinds, old.rows,
            overlay.rows,
        )  # fmt: skip
        self.current = overlay

    def release(self) -> None:
        """Working arrays back to the base."""
        self._checkout(EMPTY_OVERLAY)

    def _apply(
        self, ids: np.ndarray, touched: np.ndarray, narrowed: np.ndarray, rtol: float | None = None
    ) -> Overlay | None:
        """See :func:`._kernels.apply`; the overlay shares the current one's unchanged arrays.

        The working arrays are put back to the checked-out branch afterwards.
        """
        cur = self.current
        status, applications, n_changed, idx, lo, hi, rows = k.apply(
            self.lo, self.hi, self._saved_lo, self._saved_hi, self.rows, self.kinds,
            self.in_base, self.head, self.entry_factor, self.entry_next, self._queue,
            self._state, self._memory, self._applied, self._mark, cur.idx, cur.rows, ids,
            touched, narrowed, self.rtol if rtol is None else rtol, self.max_rounds, False,
        )  # fmt: skip
        self.applications += applications
        if Status(status) is Status.INCONSISTENT:
            return None
        if n_changed == 0:
            idx, lo, hi = cur.idx, cur.lo, cur.hi
        if len(rows) == len(cur.rows):
            rows = cur.rows
        return Overlay(idx, lo, hi, rows)

    def add_rows(
        self, overlay: Overlay, ids: np.ndarray, rtol: float | None = None
    ) -> Overlay | None:
        """The branch of ``overlay`` plus pool rows ``ids``, propagated from them (a
        variable that shrinks by less than ``rtol`` of its width wakes nobody: the graph's
        own by default; a larger one stops sooner, as soundly).

        Returns the new branch's overlay, or None when its constraints contract to empty
        (a proof). ``overlay`` itself is never changed.
        """
        self._checkout(overlay)
        return self._apply(ids, ids, _NO_INT, rtol)

    def restrict(
        self, overlay: Overlay, variables: np.ndarray, lo: np.ndarray, hi: np.ndarray
    ) -> Overlay | None:
        """The branch of ``overlay`` with ``variables`` intersected with [lo, hi] (plain
        intervals: not for headings), propagated; None when proven empty."""
        self._checkout(overlay)
        new_lo = np.maximum(self.lo[variables], lo)
        new_hi = np.minimum(self.hi[variables], hi)
        if np.any(new_lo > new_hi):
            return None
        self.lo[variables], self.hi[variables] = new_lo, new_hi
        return self._apply(_NO_INT, self.factors_of(variables), variables)

    def narrowed_to(
        self, overlay: Overlay, variables: np.ndarray, lo: np.ndarray, hi: np.ndarray
    ) -> Overlay | None:
        """The branch of ``overlay`` with ``variables`` set to ``[lo, hi]``, propagated; None
        when proven empty. The caller guarantees a sound narrowing of the branch's own
        bounds (e.g. a stronger level on a subgraph started from them): headings included,
        the bounds are taken as they are."""
        self._checkout(overlay)
        self.lo[variables], self.hi[variables] = lo, hi
        return self._apply(_NO_INT, self.factors_of(variables), variables)

    def met(self, overlay: Overlay, lo: np.ndarray, hi: np.ndarray) -> Overlay | None:
        """The branch of ``overlay`` with every variable's bounds met with ``[lo, hi]`` (a box
        of all variables that holds every solution of the branch), propagated; None when
        proven empty. Angles meet modulo 2 pi (:func:`.interval.ops.periodic_intersect`):
        the two boxes may hold a heading or a bearing in different turns."""
        mine = np.stack(self.materialize(overlay), axis=-1)
        other = np.stack([lo, hi], axis=-1)
        out = ia.intersect(mine, other)
        angles = self.angle_variables()
        with np.errstate(invalid="ignore"):  # unbounded angles (any bearing): no NaN comes out
            out[angles] = ia.periodic_intersect(mine[angles], other[angles])
        if np.any(ia.is_empty(out)):
            return None
        changed = np.flatnonzero(np.any(out != mine, axis=-1))
        if len(changed) == 0:
            return overlay
        return self.narrowed_to(overlay, changed, out[changed, 0], out[changed, 1])

    def angle_variables(self) -> np.ndarray:
        """Variables that some pooled row reads as an angle (headings, turns, bearings):
        their intervals are periodic."""
        rows, kinds = self.rows[: self.n_rows], self.kinds[: self.n_rows]
        named = [rows[:, enc.TA], rows[:, enc.TB], rows[kinds != enc.RELATIVE, enc.ANGLE]]
        variables = np.unique(np.concatenate(named))
        return variables[variables >= 0]

    def gate(
        self, overlay: Overlay, pose_x: int, landmark_xs: np.ndarray, bearing: int, distance: int
    ) -> np.ndarray:
        """:func:`._gates.gate_many` on the boxes of the branch of ``overlay``."""
        self._checkout(overlay)
        return gate_many(self.lo, self.hi, pose_x, landmark_xs, bearing, distance)

    def pairs_within_reach(
        self,
        overlay: Overlay,
        pose_xs: np.ndarray,
        radius_vars: np.ndarray,
        landmark_xs: np.ndarray,
        seen: np.ndarray,
    ) -> np.ndarray:
        """:func:`._gates.pairs_within_reach` on the boxes of the branch of ``overlay``."""
        self._checkout(overlay)
        radii = self.lo[radius_vars]
        return pairs_within_reach(self.lo, self.hi, pose_xs, radii, landmark_xs, seen)

    # ------------------------------------------------------------- reading
    def values(self, overlay: Overlay, variables: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of ``variables`` in the branch of ``overlay``."""
        o = overlay
        return k.values(o.idx, o.lo, o.hi, self.base_lo, self.base_hi, variables)

    def rows_of(self, overlay: Overlay) -> np.ndarray:
        """The factor rows the branch of ``overlay`` holds (base set and its own)."""
        ids = k.union(np.flatnonzero(self.in_base[: self.n_rows]), overlay.rows)
        rows = self.rows[ids]
        rows[:, KIND] = self.kinds[ids]
        return rows

    def materialize(self, overlay: Overlay) -> tuple[np.ndarray, np.ndarray]:
        """Full private copies of the branch's bounds."""
        lo, hi = self.base_lo.copy(), self.base_hi.copy()
        lo[overlay.idx], hi[overlay.idx] = overlay.lo, overlay.hi
        return lo, hi

    def standalone(
        self, overlay: Overlay, canonical: bool = False
    ) -> tuple[np.ndarray, np.ndarray, Arrays]:
        """The branch as a private graph: its bounds, and its rows linked, in pool order or
        (``canonical``) sorted, so that what is computed from them does not depend on the
        order in which this process pooled them (the ``lp`` level's LPs do)."""
        lo, hi = self.materialize(overlay)
        rows = self.rows_of(overlay)
        if canonical:
            rows = rows[np.lexsort(rows.T[::-1])]
        return lo, hi, linked(rows, len(lo))

    def overlay_of(self, lo: np.ndarray, hi: np.ndarray, rows: np.ndarray) -> Overlay:
        """The overlay of a branch given by full bounds and its rows beyond the base set."""
        differs = (_bits(lo) != _bits(self.base_lo)) | (_bits(hi) != _bits(self.base_hi))
        idx = np.flatnonzero(differs)
        return Overlay(idx, lo[idx], hi[idx], rows)

    def _base_widths(self) -> tuple[int, float]:
        """(infinite widths, sum of the finite ones) over the ranked variables of the base;
        the sum of huge widths (1e307 m) may overflow to inf, which only ties the rank."""
        with np.errstate(over="ignore"):
            widths = self.base_hi[self._ranked] - self.base_lo[self._ranked]
            finite = np.isfinite(widths)
            return int(np.count_nonzero(~finite)), float(np.sum(widths[finite]))

    def size_key(self, overlay: Overlay, extra: np.ndarray) -> tuple[int, float]:
        """(infinite widths, sum of finite widths) over the ranked variables and ``extra``.

        Costs the overlay, not the graph: the base's sum is corrected where they differ.
        """
        o = overlay
        n_inf, total = k.width_correction(
            o.idx, o.lo, o.hi, self.base_lo, self.base_hi, self._ranked, extra
        )
        return self._ranked_base[0] + n_inf, self._ranked_base[1] + total

    # ------------------------------------------------------------- maintenance
    def maintain(self, overlays: list[Overlay]) -> list[Overlay]:
        """Rebase and compact when the overlays or the pool have doubled since last time;
        returns the overlays re-expressed (same branches, same boxes, same rows). Any
        other overlay no longer names its branch once :attr:`maintenances` has grown."""
        load = sum(o.size for o in overlays)
        if load > max(MIN_MAINTENANCE_LOAD, 2 * self._load_after_rebase):
            overlays = self.rebase(overlays)
            self._load_after_rebase = sum(o.size for o in overlays)
            self.maintenances += 1
        if self.n_rows > max(MIN_MAINTENANCE_LOAD, 2 * self._live_after_compaction):
            overlays = self.compact(overlays)
            self._live_after_compaction = self.n_rows
            self.maintenances += 1
        return overlays

    def rebase(self, overlays: list[Overlay]) -> list[Overlay]:
        """Move the base boxes to the bounds most branches share, and rows every branch
        holds into the base set."""
        self.release()
        if not overlays:
            return overlays
        overlays = self._promote_rows(overlays)
        var = np.concatenate([o.idx for o in overlays])
        lo = np.concatenate([o.lo for o in overlays])
        hi = np.concatenate([o.hi for o in overlays])
        lo_bits, hi_bits = _bits(lo), _bits(hi)
        order = np.lexsort((hi_bits, lo_bits, var))
        first = order[k.modes(var[order], lo_bits[order], hi_bits[order], len(overlays))]
        new = (lo_bits[first] != _bits(self.base_lo[var[first]])) | (
            hi_bits[first] != _bits(self.base_hi[var[first]])
        )
        first = first[new]
        moved = var[first]
        old_lo, old_hi = self.base_lo[moved], self.base_hi[moved]
        self.base_lo[moved] = self.lo[moved] = self._saved_lo[moved] = lo[first]
        self.base_hi[moved] = self.hi[moved] = self._saved_hi[moved] = hi[first]
        self._ranked_base = self._base_widths()
        base_lo, base_hi = self.base_lo, self.base_hi
        return [
            Overlay(*k.rebased(o.idx, o.lo, o.hi, base_lo, base_hi, moved, old_lo, old_hi), o.rows)
            for o in overlays
        ]

    def _promote_rows(self, overlays: list[Overlay]) -> list[Overlay]:
        """Rows that every overlay holds join the base set."""
        ids, counts = np.unique(np.concatenate([o.rows for o in overlays]), return_counts=True)
        common = ids[counts == len(overlays)]
        if len(common) == 0:
            return overlays
        self.add_to_base(common)
        return [Overlay(o.idx, o.lo, o.hi, o.rows[~self.in_base[o.rows]]) for o in overlays]

    def compact(self, overlays: list[Overlay]) -> list[Overlay]:
        """Drop the pool rows that neither the base set nor any overlay holds."""
        self.release()
        n = self.n_rows
        live = self.in_base[:n].copy()
        for o in overlays:
            live[o.rows] = True
        keep = np.flatnonzero(live)
        renumber = np.full(n, -1, dtype=np.int64)
        renumber[keep] = np.arange(len(keep))
        rows, kinds, in_base = self.rows[keep], self.kinds[keep], self.in_base[keep]
        self.n_rows = self.n_entries = 0
        self._allocate(max(1024, 2 * len(keep)))
        self.n_rows = len(keep)
        self.rows[: self.n_rows], self.kinds[: self.n_rows] = rows, kinds
        self.in_base[: self.n_rows] = in_base
        self.head[:] = -1
        self.n_entries = k.link_rows(
            self.rows, self.n_rows, self.head, self.entry_factor, self.entry_next
        )
        self._table = k.rehash(self.rows, self.kinds, self.n_rows, len(self._table))
        return [Overlay(o.idx, o.lo, o.hi, renumber[o.rows]) for o in overlays]


def linked(rows: np.ndarray, n_vars: int) -> Arrays:
    """Factor ``rows`` on ``n_vars`` variables, with their adjacency lists: a graph the
    narrowing kernels take."""
    head = np.full(n_vars, -1, dtype=np.int64)
    entry_factor = np.zeros(N_SLOTS * max(len(rows), 1), dtype=np.int64)
    entry_next = np.zeros_like(entry_factor)
    k.link_rows(rows, len(rows), head, entry_factor, entry_next)
    return Arrays(rows, head, entry_factor, entry_next)


def _bits(values: np.ndarray) -> np.ndarray:
    """Bit patterns of float64 bounds, for exact comparison and sorting."""
    return np.ascontiguousarray(values, dtype=np.float64).view(np.int64)
